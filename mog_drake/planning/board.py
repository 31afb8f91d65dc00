"""Verdicts one planning thread shares with another while both run, each visible at its own
simulated time (Drake-free).

The lookahead plans the next decision on the table as it will be without the objects the arm
is grasping (`mog_drake.planning.lookahead`). When the next image comes before it is
done, the decision planned from that image (on the planner's thread) and the lookahead (on its
own) run side by side over largely the same groups. The lookahead writes on a `Board`, as it
goes: the group it is planning now (its claim) and each verdict once it has one. The decision
reads it through a `BoardReader`:

- a verdict is replayed with no physics (when its group's surroundings are where they were)
  once it is visible: posted no later, in simulated time, than the decision has got to;
- a group the lookahead is planning at that point is not planned a second time: the decision
  waits for its verdict, and that wait is simulated time it spends (``waited``).

A lookahead sent while the one before it still runs on its thread starts no earlier than
that one ended (``after``).

Simulated time: the lookahead's point is its request plus the time it has run on its clock
(its thread's CPU time or the wall clock: `JobClock`), the decision's its request plus
the time it has run on its own clock plus its waits. Nothing is seen before that point. A
verdict or claim posted later on the wall clock than the decision looks, though early enough
in simulated time, is missed, and the decision plans that group itself. So reading the board
never gives a decision anything it could not have had on a real cell, where the two run on
two cores.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable


class JobClock:
    """The clock a job's latency is measured on, built once (`LatencyConfig.clock`) and passed
    down: ``WALL`` (the wall clock; a job's time counts from its request, queueing included)
    or ``CPU`` (the CPU time of the job's own thread, from its start). A plain function of
    time is a clock too (`as_clock`, for tests), counted from the job's start as ``CPU``."""

    def __init__(self, name: str, from_request: bool, reader: Callable[[], Callable[[], float]]):
        self.name = name
        self.from_request = from_request  # the job's time counts from its request, not its start
        self._reader = reader

    def reader(self) -> Callable[[], float]:
        """The calling thread's time on this clock, as a function any thread can read."""
        return self._reader()

    def __repr__(self) -> str:
        return f"JobClock({self.name})"


def _this_threads_cpu() -> Callable[[], float]:
    clock_id = time.pthread_getcpuclockid(threading.get_ident())
    return lambda: time.clock_gettime(clock_id)


WALL = JobClock("wall", True, lambda: time.perf_counter)
CPU = JobClock("cpu", False, _this_threads_cpu)


def as_clock(clock: JobClock | Callable[[], float]) -> JobClock:
    """``clock``, or a function of time as a clock (tests)."""
    if isinstance(clock, JobClock):
        return clock
    return JobClock("custom", False, lambda: clock)


class Board:
    """What a planning thread (the poster) shares while it runs: its claims (the group it is
    planning, from when to when) and its verdicts, each stamped with the simulated time it
    happened: ``t_request`` plus the poster's time on ``clock`` since `start` (a `JobClock`,
    or a function, for tests). The poster calls `start`, then `claim` / `post`,
    then `finish`; any other thread reads it through a `BoardReader`."""

    def __init__(
        self, t_request: float, clock: JobClock | Callable[[], float] = WALL, after: Board | None = None
    ):
        self.t_request = t_request
        self._clock = as_clock(clock)
        self._after = after  # a board whose poster holds this one's thread until it finishes
        self.end: float | None = None  # the simulated time the poster finished
        self._now: Callable[[], float] | None = None
        self._c0 = 0.0
        self._cond = threading.Condition()
        self._entries: list[tuple[float, object]] = []  # (stamp, verdict), in stamp order
        # (from, to or None while open, group, around): what the poster planned when.
        self._claims: list[list] = []
        self._posted: set[int] = set()  # ids of the entries posted
        if self._clock.from_request:  # e.g. the wall clock: queueing included
            self.start()

    def start(self) -> float:
        """On the poster's thread, as it starts: its clock starts here (at the request on a
        clock that counts from it), and its simulated time no earlier than the end of ``after``'s poster, which
        ran on the same thread before it (on the wall clock, time from the request counts that
        already). Returns how much later than ``t_request`` it starts (s), once: 0 after."""
        if self._now is not None:
            return 0.0
        self._now = self._clock.reader()
        self._c0 = self._now()
        t0 = self.t_request
        if self._after is not None and self._after.end is not None and not self._clock.from_request:
            self.t_request = max(t0, self._after.end)
        return self.t_request - t0

    def stamp(self) -> float:
        """The poster's simulated time now (on its own thread)."""
        self.start()
        return self._at()

    def _at(self) -> float:
        """The poster's simulated time now, once it has started (from any thread)."""
        return self.t_request + self._now() - self._c0

    def claim(self, group, around) -> None:
        """The poster plans ``group`` (its ids) with ``around`` (see `decision._around`) now."""
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
    it has spent waiting for the poster, beyond its own clock."""

    def __init__(self, board: Board, t_request: float, clock: JobClock | Callable[[], float] = WALL):
        self.board = board
        self.t_request = t_request
        self._now = as_clock(clock).reader()
        self._c0 = self._now()
        self.waited = 0.0
        self.got: list = []  # every verdict `new` returned, in order
        self._seen = 0

    def t(self) -> float:
        """The plan's simulated time now."""
        return self.t_request + self._now() - self._c0 + self.waited

    def _by(self, stamp: float, t: float) -> bool:
        """Whether what the poster did at simulated time ``stamp`` is seen at ``t``."""
        return stamp <= t + 1e-9

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
            while claim[1] is None:
                self.board._cond.wait()
            end = claim[1]
        self.waited += max(0.0, end - self.t())

    def _claim_at(self, t: float) -> list | None:
        """The poster's last claim begun by simulated time ``t`` (the board's lock held)."""
        return next((c for c in reversed(self.board._claims) if self._by(c[0], t)), None)
