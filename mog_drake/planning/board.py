"""Verdicts one planning thread shares with another while both run, each visible at its own
simulated time (Drake-free).

The lookahead plans the next decision on the table as it will be without the objects the arm
is grasping (`mog_drake.planning.picking.lookahead`). When the next image comes before it is
done, the decision planned from that image (on the planner's thread) and the lookahead (on its
own) run side by side over largely the same groups. The lookahead writes on a `Board`, as it
goes: the group it is planning now (its claim) and each verdict once it has one. The decision
reads it through a `BoardReader`:

- a verdict is replayed with no physics (when its group's surroundings are where they were)
  once it is visible: posted no later, in simulated time, than the decision has got to;
- a group the lookahead is planning at that point is not planned a second time: the decision
  waits for its verdict, and that wait is simulated time it spends (``waited``).

The decision's assistant (`mog_drake.planning.picking.assist`) runs on the lookahead's core
when that is idle, and the two boards go both ways: the decision reads the assistant's as it
reads a lookahead's, and the assistant reads the decision's to skip the groups it has begun
(`BoardReader.claims`) and to stop once it has a grasp (`BoardReader.stopped`). A job that
follows a poster on the same thread starts no earlier than that poster ended (``after``).

Simulated time: the lookahead's point is its request plus the time it has run on its clock
(its thread's CPU time, its modelled time or the wall clock: `mog_drake.planning.clock`), the
decision's its request plus the time it has run on its own clock plus its waits. Nothing is
seen before that point. On the CPU and wall clocks, a verdict or claim posted later on the
wall clock than the decision looks, though early enough in simulated time, is missed, and
the decision plans that group itself. So reading the board never gives a decision anything
it could not have had on a real cell, where the two run on two cores. On the modelled clock
the reads are exact: a decision that reads at simulated time t first waits (on the wall
clock) until the poster's modelled time is past t or it has finished, so it sees all it
would on a real cell, and the same on every run (``sync``).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable

from mog_drake.planning.clock import thread_clock

SYNC_POLL_S = 0.002  # how often a synced read looks at the poster's modelled clock (wall s)


class Board:
    """What a planning thread (the poster) shares while it runs: its claims (the group it is
    planning, from when to when) and its verdicts, each stamped with the simulated time it
    happened: ``t_request`` plus the poster's time on ``clock`` since `start` ("cpu", "wall",
    "modelled", or a function, for tests). The poster calls `start`, then `claim` / `post`,
    then `finish`; any other thread reads it through a `BoardReader`."""

    def __init__(
        self, t_request: float, clock: str | Callable[[], float] = "wall", after: Board | None = None
    ):
        self.t_request = t_request
        self._clock = clock
        self._after = after  # a board whose poster holds this one's thread until it finishes
        self.end: float | None = None  # the simulated time the poster finished
        self._now: Callable[[], float] | None = None
        self._c0 = 0.0
        self._cond = threading.Condition()
        self._entries: list[tuple[float, object]] = []  # (stamp, verdict), in stamp order
        # (from, to or None while open, group, around): what the poster planned when.
        self._claims: list[list] = []
        self._posted: set[int] = set()  # ids of the entries posted
        # The poster's waits for another board's verdicts (s, its simulated time, as its
        # latency: `BoardReader`'s ``own``), and the claim it is waiting for now, if any.
        self._lag = 0.0
        self._waiting: tuple[Board, list] | None = None
        if clock == "wall":  # a wall-clock latency counts from the request (queueing included)
            self.start()

    def start(self) -> float:
        """On the poster's thread, as it starts: its clock starts here ("wall": at the
        request), and its simulated time no earlier than the end of ``after``'s poster, which
        ran on the same thread before it (on the wall clock, time from the request counts that
        already). Returns how much later than ``t_request`` it starts (s), once: 0 after."""
        if self._now is not None:
            return 0.0
        self._now = thread_clock(self._clock)
        self._c0 = self._now()
        t0 = self.t_request
        if self._after is not None and self._after.end is not None and self._clock != "wall":
            self.t_request = max(t0, self._after.end)
        return self.t_request - t0

    def stamp(self) -> float:
        """The poster's simulated time now (on its own thread)."""
        self.start()
        return self._at()

    def _at(self) -> float:
        """The poster's simulated time now, once it has started (from any thread)."""
        return self.t_request + self._now() - self._c0 + self._lag

    def reached(self, t: float, at: bool = False) -> bool:
        """Whether the poster has finished or its simulated time is past ``t`` (``at``: at
        least ``t``), read from any thread (the board's lock held); not before it starts.
        Past, not at, for a reader that sees what is posted at ``t``: the poster's work
        between two checks costs no modelled time, so it may yet claim or post at ``t``.
        A poster waiting for another's claim posts nothing before that claim ends, which is
        no earlier than the other's time now: it counts as being there."""
        if self.end is not None:
            return True
        if self._now is None:
            return False
        waiting = self._waiting  # read before the lag: `resume` adds the lag first
        now = self._at()
        if waiting is not None:
            other, claim = waiting
            bound = other._at()  # read before the claim's end: it ends no earlier
            end = claim[1]
            now = max(now, bound if end is None else end)
        return now >= t - 1e-9 if at else now > t + 1e-9

    def hold(self, other: Board, claim: list) -> None:
        """On the poster's thread: it waits, from now, for ``other``'s ``claim`` to end."""
        self._waiting = (other, claim)

    def resume(self, waited: float) -> None:
        """On the poster's thread: its wait is over, and took ``waited`` s of simulated
        time, which its stamps count from now on."""
        self._lag += waited
        self._waiting = None

    def claim(self, group, around) -> None:
        """The poster plans ``group`` (its ids) with ``around`` (see `picking._around`) now."""
        with self._cond:
            s = self.stamp()
            self._close(s)
            self._claims.append([s, None, tuple(group), around])
            self._cond.notify_all()

    def post(self, entry) -> None:
        """A verdict (a memory entry of `picking.next_pick`); it ends the open claim. An entry
        posted before (the same object) is not posted again."""
        with self._cond:
            if id(entry) in self._posted:
                return
            self._posted.add(id(entry))
            s = self.stamp()
            self._close(s)
            self._entries.append((s, entry))
            self._cond.notify_all()

    def finish(self) -> None:
        """The poster is done: nothing more will be claimed or posted."""
        with self._cond:
            self.end = self.stamp()
            self._close(self.end)
            self._cond.notify_all()

    def _close(self, s: float) -> None:
        if self._claims and self._claims[-1][1] is None:
            self._claims[-1][1] = s


class BoardReader:
    """A plan's view of ``board``: the plan was requested at simulated time ``t_request`` and
    starts now, on this thread, timed on ``clock`` (as `Board`). ``waited``: simulated time
    it has spent waiting for the poster, beyond its own clock. ``sync`` (on the modelled
    clock): each read first waits until the poster has got as far (`Board.reached`), so it
    sees all that was posted by then.

    ``own``: the board the plan itself posts on (the lookahead's, or the decision's for its
    assistant): its waits for this board's verdicts count in its stamps, and while it waits
    it counts as being at this poster's time (`Board.reached`), so a thread that reads it
    synced is not held up by a wait for its own claim.

    ``yields``: at a tie in simulated time the poster goes first. The plan sees only what was
    posted (claimed, finished) before its time, not at it, so a synced read waits only until
    the poster has got to its time. Two threads that read each other's boards synced, one
    yielding, never wait for each other: the one that does not yield waits for the other to
    be past its time, the one that yields for the other to be at its own. (The decision's
    assistant reads the decision's board unsynced: the decision's reads do not yield.)"""

    def __init__(
        self,
        board: Board,
        t_request: float,
        clock: str | Callable[[], float] = "wall",
        sync: bool = False,
        yields: bool = False,
        own: Board | None = None,
    ):
        self.board = board
        self._own = own
        self.t_request = t_request
        self._now = thread_clock(clock)
        self._c0 = self._now()
        self._sync = sync
        self._yields = yields
        self.waited = 0.0
        self.got: list = []  # every verdict `new` returned, in order
        self._seen = 0

    def t(self) -> float:
        """The plan's simulated time now; with ``sync``, once the poster has got as far."""
        t = self.t_request + self._now() - self._c0 + self.waited
        if self._sync:
            with self.board._cond:
                while not self.board.reached(t, at=self._yields):
                    self.board._cond.wait(SYNC_POLL_S)
        return t

    def _by(self, stamp: float, t: float) -> bool:
        """Whether what the poster did at simulated time ``stamp`` is seen at ``t``."""
        return stamp < t - 1e-9 if self._yields else stamp <= t + 1e-9

    def new(self) -> list:
        """The verdicts visible by now that were not returned before, in the poster's order."""
        t = self.t()
        with self.board._cond:
            entries = self.board._entries
            k = self._seen
            while k < len(entries) and self._by(entries[k][0], t):
                k += 1
            out = [e for _, e in entries[self._seen : k]]
            self._seen = k
        self.got += out
        return out

    def claimed(self) -> tuple | None:
        """(group, around) the poster is planning at this plan's simulated time, as far as is
        known on the wall clock now; None if nothing is."""
        t = self.t()
        with self.board._cond:
            claim = self._claim_at(t)
            if claim is None or (claim[1] is not None and self._by(claim[1], t)):
                return None
            return claim[2], claim[3]

    def wait(self) -> None:
        """Waits (on the wall clock) until the claim open at this plan's simulated time ends,
        then moves this plan's time on to that point: it waited for the verdict."""
        with self.board._cond:
            claim = self._claim_at(self.t())
            if claim is None:
                return
            if self._own is not None:
                self._own.hold(self.board, claim)
            while claim[1] is None:
                self.board._cond.wait()
            end = claim[1]
        waited = max(0.0, end - self.t())
        self.waited += waited
        if self._own is not None:
            self._own.resume(waited)

    def claims(self) -> list[tuple]:
        """(group, around) of every claim the poster had begun by this plan's simulated time,
        as far as is known on the wall clock now."""
        t = self.t()
        with self.board._cond:
            return [(c[2], c[3]) for c in self.board._claims if self._by(c[0], t)]

    def stopped(self, final: Callable[[object], bool]) -> bool:
        """Whether the poster had finished, or posted a verdict for which ``final`` is true,
        by this plan's simulated time, as far as is known on the wall clock now."""
        t = self.t()
        with self.board._cond:
            if self.board.end is not None and self._by(self.board.end, t):
                return True
            return any(final(e) for s, e in self.board._entries if self._by(s, t))

    def _claim_at(self, t: float) -> list | None:
        """The poster's last claim begun by simulated time ``t`` (the board's lock held)."""
        return next((c for c in reversed(self.board._claims) if self._by(c[0], t)), None)


class Horizon:
    """How far the Diagram has got in simulated time, for a thread that plans ahead of it on
    the planner's core, which the next decision needs once its image comes: the lookahead's
    assistant (`mog_drake.planning.picking.assist` with ``until``). The Diagram's thread calls
    `reach` at each planner update, with ``image`` at the one that starts that decision, and
    `close` when the run ends. The assistant asks `came` at its own simulated time, which
    waits (on the wall clock) until the Diagram has got that far: so its answer, and where the
    assistant stops, is the same on every run, whichever thread runs ahead."""

    def __init__(self):
        self._cond = threading.Condition()
        self._t = -math.inf  # the last update's simulated time
        self.image: float | None = None  # the simulated time the image came
        self._closed = False

    def reach(self, t: float, image: bool = False) -> None:
        """The Diagram is at simulated time ``t``; ``image``: the next image came then."""
        with self._cond:
            self._t = max(self._t, t)
            if image and self.image is None:
                self.image = t
            self._cond.notify_all()

    def close(self) -> None:
        """The run ended: nothing more will come."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    def came(self, t: float) -> bool:
        """Whether the image came by simulated time ``t``, or the run ended."""
        with self._cond:
            while self.image is None and self._t < t - 1e-9 and not self._closed:
                self._cond.wait()
            return self._closed or (self.image is not None and self.image <= t + 1e-9)
