"""The Planner system: a perceived Scene in, a pick decision out (see `mog_drake.systems.perception`
for how the three application systems talk)."""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from mog_drake.planning.board import Board, BoardReader, Horizon
from mog_drake.planning.config import PlannerSpec
from mog_drake.planning.picking import (
    PickDecision,
    assist,
    lookahead,
    next_pick,
    tally_misses,
    without_grasped,
)
from mog_drake.planning.planner import draws_at_random
from mog_drake.systems.jobs import LatencyConfig, Worker
from mog_drake.systems.perception import Perceived, _Immutable, _Slot


@dataclass
class Decision(_Immutable):
    counter: int = -1
    decision: PickDecision | None = None
    objects_seen: int = 0
    recent: tuple = ()  # the last grasps issued, not to be repeated
    failures: tuple = ()  # groups found to have no grasp (see next_pick)
    unrecognised_grasps: int = 0  # grasps of unrecognised blobs issued in a row
    rng: np.random.Generator | None = None  # the planner's random draws, after this decision
    t_request: float = 0.0  # simulated time the scene became visible (the planning request)
    t_visible: float = 0.0  # simulated time this decision became visible
    wall_time: float = 0.0  # the planning job's wall time (s)
    cpu_time: float = 0.0  # the planning job's CPU time (s)
    previous: Decision | None = None  # the state this one was planned from
    pushes: int = 0  # push-mog: pushes decided so far, this one included
    # (shape, x, y) of the objects this decision's grasp means to take, and the failed grasps
    # per object as of its image ((shape, x, y, count): see tally_misses).
    targets: tuple = ()
    misses: tuple = ()
    # The lookahead's memory for this plan: "used" (visible at its image), "merged" (it came
    # in while the plan ran: merge_lookahead), "dropped" (never in time), or "" (none ran).
    lookahead: str = ""
    assisted: bool = False  # half its groups were planned on the lookahead's core (assist)
    # Groups its lookahead's assistant planned on the planner's core (assist_lookahead).
    helped: int = 0


class PlannerSystem(LeafSystem):
    """scene -> decision: Alg. 1 (mog) or the single-object baseline (sog) once per new scene,
    as ``spec`` (`PlannerSpec`) says, with ``planner`` (a GraspPlanner), as a job on a worker
    thread whose decision becomes visible after its latency (`mog_drake.systems.jobs`). The
    random draws come from a Generator seeded with ``spec.seed`` that lives in the Context's
    state. A retaken scene (the table changed before the last decision was used) is planned
    from the state before that decision, which was never executed."""

    REMEMBER = 3  # grasps not to repeat: the last three issued
    # Grasps of unrecognised blobs in a row before the run ends on them: each failed one moves
    # the blob, so the planner would otherwise try a new outline until the time limit.
    MAX_UNRECOGNISED_GRASPS = 3

    def __init__(
        self,
        planner,
        spec: PlannerSpec | None = None,
        period: float = 0.01,
        latency: LatencyConfig | None = None,
        block: bool = True,
        ahead_planner=None,
    ):
        super().__init__()
        self._planner = planner
        # The lookahead's own planner (its physics check keeps a built plant: one per thread).
        self._ahead_planner = ahead_planner
        self._spec = spec or PlannerSpec()
        self._spec.check()
        latency = latency or LatencyConfig()
        self._latency = latency.of("planning")
        self._clock = latency.clock
        self._block = block
        self._worker = Worker("planner", latency.clock)
        self._ahead_worker = Worker("lookahead", latency.clock)
        self._lookahead = (
            ahead_planner is not None
            and self._spec.lookahead
            and self._spec.remember_failures
            and self._spec.mode in ("mog", "push-mog")
        )
        # The decision's assistant on the lookahead's core when that is idle (see
        # mog_drake.planning.picking.assist): deterministic checks, measured latencies.
        assistable = (
            self._lookahead
            and self._latency is None
            and not draws_at_random(self._spec.method)
            and self._spec.decision_budget_s == 0
        )
        self._assist = assistable and self._spec.assist
        # The lookahead's assistant on the planner's core while the arm moves, until the next
        # image (assist_lookahead): the same terms.
        self._assist_ahead = assistable and self._spec.assist_lookahead
        self._horizons: list[Horizon] = []  # each assistant's, closed when the run ends
        self._scene = self.DeclareAbstractInputPort("scene", AbstractValue.Make(Perceived()))
        self._state = self.DeclareAbstractState(
            AbstractValue.Make(Decision(rng=np.random.default_rng(self._spec.seed)))
        )
        self._job = self.DeclareAbstractState(AbstractValue.Make(_Slot()))
        self._ahead = self.DeclareAbstractState(AbstractValue.Make(_Slot()))
        # The last job sent to the lookahead's thread (a lookahead or an assistant), its
        # board in its info: a job sent after it starts no earlier than it ends.
        self._last_ahead = self.DeclareAbstractState(AbstractValue.Make(_Slot()))
        # The lookahead's assistant, its (board, Horizon) in its info: the next decision
        # starts on the planner's thread no earlier than it ends.
        self._helper = self.DeclareAbstractState(AbstractValue.Make(_Slot()))
        self.DeclareAbstractOutputPort(
            "decision",
            lambda: AbstractValue.Make(Decision()),
            self._out,
            prerequisites_of_calc={self.all_state_ticket()},
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)

    def shutdown(self) -> None:
        for h in self._horizons:
            h.close()  # an assistant waiting for the next image stops
        self._worker.shutdown()
        self._ahead_worker.shutdown()

    def _update(self, context, state) -> None:
        t = context.get_time()
        cur = context.get_abstract_state(self._state).get_value()
        job = context.get_abstract_state(self._job).get_value().job
        if job is not None and job.visible(t, self._latency, self._block):
            job_counter = job.counter
            d, rng = job.result()
            base, n_objects, scene, misses, ahead_use, assisted, helped_by = job.info
            if ahead_use == "late":
                ahead_use = "merged" if d.merged else "dropped"
            recent = base.recent + ((tuple(float(v) for v in d.grasp),) if d.grasp is not None else ())
            if d.status == "grasp":
                blob_grasps = base.unrecognised_grasps + 1 if d.unrecognised else 0
            else:  # a clear table, or given up: the count stands
                blob_grasps = base.unrecognised_grasps
            cur = Decision(
                job.counter,
                d,
                n_objects,
                recent[-self.REMEMBER :],
                d.failures,
                blob_grasps,
                rng,
                job.t_request,
                t,
                job.wall_time(),
                job.cpu_time(),
                dataclasses.replace(base, previous=None),  # one step back is all a retake needs
                base.pushes + (d.status == "push"),
                _targets(d, scene),
                misses,
                ahead_use,
                assisted,
                helped_by.result() if helped_by is not None else 0,
            )
            state.get_mutable_abstract_state(self._state).set_value(cur)
            state.get_mutable_abstract_state(self._job).set_value(_Slot())
            job = None
            # After a grasp, the lookahead plans this image without its objects; after a push
            # whose grasp follows at once, the table the simulated push left without them.
            chained = d.status == "push" and d.grasp is not None and d.after is not None
            if self._lookahead and (d.status == "grasp" or chained) and not d.unrecognised:
                # push-mog: it considers pushes too, with the pushes left after this decision.
                # It writes on a board as it goes, for the next plan if that starts first.
                # Its assistant, if any, posts on ``helper``, on the planner's idle core.
                board = Board(t, self._clock, after=self._thread_board(state))
                helper = Board(t, self._clock) if self._assist_ahead else None
                table = d.after if chained else scene
                ahead = self._ahead_worker.submit(
                    self._look,
                    table,
                    d,
                    copy.deepcopy(rng),
                    cur.recent,
                    self._spec.max_pushes - cur.pushes,
                    board,
                    helper,
                    t_request=t,
                    counter=job_counter,
                    info=board,
                    delay=board.start,
                )
                state.get_mutable_abstract_state(self._ahead).set_value(_Slot(ahead))
                state.get_mutable_abstract_state(self._last_ahead).set_value(_Slot(ahead))
                if helper is not None:
                    horizon = Horizon()
                    self._horizons.append(horizon)
                    aid = self._worker.submit(
                        self._help,
                        without_grasped(table, d),
                        d.failures,
                        cur.recent,
                        board,
                        helper,
                        horizon,
                        t_request=t,
                        counter=job_counter,
                        info=(helper, horizon),
                    )
                    state.get_mutable_abstract_state(self._helper).set_value(_Slot(aid))
        p = self._scene.Eval(context)
        last = job.counter if job is not None else cur.counter
        image = not (job is not None or p.scene is None or p.counter <= last)
        aid = state.get_mutable_abstract_state(self._helper).get_value().job
        if aid is not None:
            # Before anything here may wait for a job: the lookahead's assistant stops at the
            # image, and the decision starts on the planner's thread once it has.
            aid.info[1].reach(t, image)
        if not image:
            return
        if aid is not None:
            state.get_mutable_abstract_state(self._helper).set_value(_Slot())
        # A retake replaces a decision that was never executed: plan from the state before it.
        base = cur.previous if p.retake and cur.previous is not None else cur
        rng = copy.deepcopy(base.rng)  # the state's value is never changed in place
        memory = base.failures
        ahead = context.get_abstract_state(self._ahead).get_value().job
        late, ahead_use = None, ""
        if ahead is not None:
            # The lookahead's memory if it is visible by now, as any planning job's result is
            # after its latency (it planned the table this image shows, less the objects
            # grasped since). If not, with measured latencies this plan reads its board: its
            # verdicts as they become visible, and it waits for those of the groups it is
            # planning (`mog_drake.planning.board`); else it is dropped, and its thread
            # finishes it unused.
            ahead_use = "dropped"
            if ahead.counter == cur.counter and ahead.visible(t, self._latency, self._block):
                memory, ahead_use = ahead.result(), "used"
            elif ahead.counter == cur.counter and self._spec.merge_lookahead and self._latency is None:
                late, ahead_use = ahead.info, "late"  # its board
            state.get_mutable_abstract_state(self._ahead).set_value(_Slot())
        # Objects the robot grasped MAX_MISSES times without taking them are not planned again.
        misses, given_up = tally_misses(base.misses, base.targets, p.scene)
        avoid, failures = base.recent, memory if self._spec.remember_failures else None
        post = None
        # This plan starts on the planner's thread once the lookahead's assistant ends.
        after = aid.info[0] if aid is not None else None
        last = state.get_mutable_abstract_state(self._last_ahead).get_value().job
        # On the modelled clock the lookahead's core is idle in simulated time whenever there
        # is no late lookahead (a lookahead in time is done; another job there ended with its
        # decision), and a job still finishing there on the wall clock only delays the
        # assistant's start (its ``after``): whether to assist is decided the same on every run.
        idle = last is None or last.future.done() or self._clock == "modelled"
        if self._assist and late is None and idle:
            # The lookahead's core is idle: half the groups are planned there (its board is
            # this plan's ``late``), and it reads this plan's board (``post``).
            post = Board(t, self._clock, after=after)
            helper = Board(t, self._clock, after=self._thread_board(state))
            helped = self._ahead_worker.submit(
                self._aid,
                p.scene,
                avoid,
                failures or (),
                given_up,
                post,
                helper,
                t_request=t,
                counter=p.counter,
                info=helper,
                delay=helper.start,
            )
            state.get_mutable_abstract_state(self._last_ahead).set_value(_Slot(helped))
            late = helper
        start = post if post is not None else Board(t, self._clock, after=after)
        job = self._worker.submit(
            self._plan,
            p.scene,
            rng,
            avoid,
            failures,
            base.unrecognised_grasps < self.MAX_UNRECOGNISED_GRASPS,
            self._spec.max_pushes - base.pushes,
            given_up,
            late,
            post,
            start,
            t_request=t,
            counter=p.counter,
            info=(base, len(p.scene), p.scene, misses, ahead_use, post is not None, aid),
            waited=lambda out: out[0].waited,
            delay=start.start,
        )
        state.get_mutable_abstract_state(self._job).set_value(_Slot(job))

    def _plan(self, scene, rng, avoid, failures, grasp_unrecognised, pushes_left, exclude, late, post, start):
        # Started already (its delay): its time is its request, or the end of the lookahead's
        # assistant before it. On the modelled clock its reads are exact (`BoardReader`'s sync).
        sync = self._clock == "modelled"
        source = (
            None if late is None else BoardReader(late, start.t_request, self._clock, sync=sync, own=post)
        )
        if post is not None:
            post.start()  # its stamps count this thread's time from here
        try:
            d = next_pick(
                scene,
                self._planner,
                self._spec,
                rng,
                avoid=avoid,
                failures=failures,
                grasp_unrecognised=grasp_unrecognised,
                pushes_left=pushes_left,
                exclude=exclude,
                late=source,
                post=post,
            )
        finally:
            if post is not None:
                post.finish()  # the assistant stops
        return d, rng

    def _look(self, scene, d, rng, avoid, pushes_left, board, helper):
        # Started already (its delay). It reads its assistant's board as a decision does.
        board.start()
        sync = self._clock == "modelled"
        late = (
            None
            if helper is None
            else BoardReader(helper, board.t_request, self._clock, sync=sync, own=board)
        )
        return lookahead(
            scene,
            d,
            self._ahead_planner,
            self._spec,
            rng,
            avoid,
            pushes_left=pushes_left,
            board=board,
            late=late,
        )

    def _help(self, scene, failures, avoid, main, board, horizon):
        # The lookahead's assistant, on the planner's thread; it yields to the lookahead at a
        # tie in simulated time, so their synced reads never wait for each other.
        board.start()
        reader = BoardReader(main, board.t_request, self._clock, sync=self._clock == "modelled", yields=True)
        return assist(scene, self._planner, self._spec, reader, board, avoid, failures, until=horizon.came)

    def _aid(self, scene, avoid, failures, exclude, main, board):
        # Started already (its delay): its time is its request, or the end of the job before.
        # On the modelled clock its reads of the decision's board are exact too, yielding at a
        # tie (as the lookahead's assistant's): the same on every run, and the two never wait
        # for each other (the decision's own waits for this board count as its time: ``own``).
        main = BoardReader(main, board.t_request, self._clock, sync=self._clock == "modelled", yields=True)
        return assist(scene, self._ahead_planner, self._spec, main, board, avoid, failures, exclude)

    def _thread_board(self, state) -> Board | None:
        """The board of the last job sent to the lookahead's thread, if any (a job of its that
        raised re-raises here, in the Diagram's thread)."""
        last = state.get_mutable_abstract_state(self._last_ahead).get_value().job
        if last is None:
            return None
        if last.future.done() and last.future.exception() is not None:
            last.future.result()
        return last.info

    def _out(self, context, output) -> None:
        output.set_value(context.get_abstract_state(self._state).get_value())


def _targets(d: PickDecision, scene) -> tuple:
    """(shape, x, y) of the objects decision ``d``'s grasp means to take (on the table the
    push leaves, if its grasp follows a push at once); none for blobs or a push alone."""
    if d.grasp is None or d.unrecognised or d.status not in ("grasp", "push"):
        return ()
    table = d.after if d.status == "push" and d.after is not None else scene
    return tuple(
        (table.objects[i].shape, float(table.objects[i].x), float(table.objects[i].y)) for i in d.expected
    )
