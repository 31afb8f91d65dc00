"""The Planner system: a perceived Scene in, a pick decision out (see `mog_drake.systems.perception`
for how the three application systems talk)."""

from __future__ import annotations

import copy
import dataclasses
import functools
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from mog_drake.config import LatencyConfig
from mog_drake.planning.config import PlannerSpec
from mog_drake.planning.decision import PickDecision
from mog_drake.planning.lookahead import lookahead
from mog_drake.planning.picking import missed, next_pick, tally_misses, tally_suspects, wary_outlines
from mog_drake.planning.planner import jaw_footprints
from mog_drake.systems.jobs import Worker, clock_of
from mog_drake.systems.messages import Decision, Perceived, Slot


@dataclass(frozen=True)
class _Request:
    """What a planning job was asked with, for the Decision it becomes."""

    base: Decision  # the state it was planned from
    objects: int  # objects seen in its image
    scene: object  # the perceived scene
    misses: tuple  # failed grasps per object as of its image
    missed_grasps: tuple  # as Decision.missed_grasps
    suspects: tuple  # as Decision.suspects
    lookahead: str  # as Decision.lookahead


class PlannerSystem(LeafSystem):
    """scene -> decision: Alg. 1 (mog) or the single-object baseline (sog) once per new scene,
    as ``spec`` (`PlannerSpec`) says, with ``planner`` (a GraspPlanner), as a job on a worker
    thread whose decision becomes visible after its latency (`mog_drake.systems.jobs`). The
    random draws come from a Generator seeded with ``spec.seed`` that lives in the Context's
    state. A retaken scene (the table changed before the last decision was used) is planned
    from the state before that decision, which was never executed.

    With ``ahead_planner`` (its own physics check: a built plant is one thread's) and
    ``spec.lookahead.enabled``, once a grasp is decided the next decision is planned on a second
    thread while the arm moves (`mog_drake.planning.lookahead`)."""

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
        self._ahead_planner = ahead_planner
        self._spec = spec or PlannerSpec()
        self._spec.check()
        latency = latency or LatencyConfig()
        self._latency = latency.of("planning")
        self._block = block
        self._worker = Worker("planner", clock_of(latency))
        self._ahead_worker = Worker("lookahead", clock_of(latency))
        self._lookahead = (
            ahead_planner is not None and self._spec.lookahead.enabled and self._spec.loop.remember_failures
        )
        self._scene = self.DeclareAbstractInputPort("scene", AbstractValue.Make(Perceived()))
        self._state = self.DeclareAbstractState(
            AbstractValue.Make(Decision(rng=np.random.default_rng(self._spec.seed)))
        )
        self._job = self.DeclareAbstractState(AbstractValue.Make(Slot()))
        # The lookahead for the next decision, until that decision takes (or drops) it.
        self._ahead = self.DeclareAbstractState(AbstractValue.Make(Slot()))
        # The last lookahead sent, kept after it was taken or dropped: if it raised, the next
        # one's start re-raises it.
        self._last_ahead = self.DeclareAbstractState(AbstractValue.Make(Slot()))
        self.DeclareAbstractOutputPort(
            "decision",
            lambda: AbstractValue.Make(Decision()),
            self._out,
            prerequisites_of_calc={self.all_state_ticket()},
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)

    def shutdown(self) -> None:
        self._worker.shutdown()
        self._ahead_worker.shutdown()

    def _update(self, context, state) -> None:
        t = context.get_time()
        job = context.get_abstract_state(self._job).get_value().job
        if job is not None and job.visible(t, self._latency, self._block):
            self._collect(job, t, state)
            job = None
        p = self._scene.Eval(context)
        cur = state.get_mutable_abstract_state(self._state).get_value()
        last = job.counter if job is not None else cur.counter
        if job is None and p.scene is not None and p.counter > last:
            self._decide(p, cur, t, state)

    def _collect(self, job, t: float, state) -> None:
        """A decision became visible: it is the state now, and a lookahead starts after a grasp."""
        d, rng = job.result()
        req: _Request = job.info
        used = req.lookahead
        base = req.base
        recent = base.recent + ((tuple(float(v) for v in d.grasp),) if d.grasp is not None else ())
        if d.status == "grasp":
            blob_grasps = base.unrecognised_grasps + 1 if d.unrecognised else 0
        else:  # a clear table, or given up: the count stands
            blob_grasps = base.unrecognised_grasps
        cur = Decision(
            counter=job.counter,
            decision=d,
            objects_seen=req.objects,
            blobs_seen=int(req.scene.meta.get("unrecognised_blobs", 0)),
            recent=recent[-self.REMEMBER :],
            failures=d.failures,
            unrecognised_grasps=blob_grasps,
            rng=rng,
            t_request=job.t_request,
            t_visible=t,
            wall_time=job.wall_time(),
            cpu_time=job.cpu_time(),
            previous=dataclasses.replace(base, previous=None),  # one step back is all a retake needs
            pushes=base.pushes + (d.status == "push"),
            targets=_targets(d, req.scene),
            misses=req.misses,
            missed_grasps=req.missed_grasps,
            suspects=req.suspects,
            lookahead=used,
        )
        state.get_mutable_abstract_state(self._state).set_value(cur)
        state.get_mutable_abstract_state(self._job).set_value(Slot())
        # After a grasp, the lookahead plans this image without its objects; after a push
        # whose grasp follows at once, the table the simulated push left without them.
        chained = d.status == "push" and d.grasp is not None and d.after is not None
        if self._lookahead and (d.status == "grasp" or chained) and not d.unrecognised:
            self._look_ahead(d.after if chained else req.scene, d, rng, cur, job.counter, t, state=state)

    def _look_ahead(
        self, table, d: PickDecision, rng, cur: Decision, counter: int, t: float, *, state
    ) -> None:
        """Starts the lookahead (push-mog: with the pushes left after this decision), on its
        own thread (a `Worker`: no earlier in simulated time than the one before it ended)."""
        self._raise_lookahead_fault(state)
        ahead = self._ahead_worker.submit(
            functools.partial(lookahead, pushes_left=self._spec.pushes.max_per_table - cur.pushes),
            table,
            d,
            self._ahead_planner,
            self._spec,
            copy.deepcopy(rng),
            cur.recent,
            t_request=t,
            counter=counter,
        )
        state.get_mutable_abstract_state(self._ahead).set_value(Slot(ahead))
        state.get_mutable_abstract_state(self._last_ahead).set_value(Slot(ahead))

    def _decide(self, p: Perceived, cur: Decision, t: float, state) -> None:
        """A new image: its decision starts on the planner's thread."""
        # A retake replaces a decision that was never executed: plan from the state before it.
        base = cur.previous if p.retake and cur.previous is not None else cur
        rng = copy.deepcopy(base.rng)  # the state's value is never changed in place
        memory = base.failures
        ahead = state.get_mutable_abstract_state(self._ahead).get_value().job
        used = ""
        if ahead is not None:
            # The lookahead's memory if it is visible by now, as any planning job's result is
            # after its latency (it planned the table this image shows, less the objects
            # grasped since); else it is dropped, and its thread finishes it unused.
            used = "dropped"
            if ahead.counter == cur.counter and ahead.visible(t, self._latency, self._block):
                memory, used = ahead.result(), "used"
            state.get_mutable_abstract_state(self._ahead).set_value(Slot())
        # Objects the robot grasped MAX_MISSES times without taking them are not planned again.
        misses, given_up = tally_misses(base.misses, base.targets, p.scene)
        # The jaws of the last grasps that took none of their objects stay off where they were.
        gone = base.missed_grasps
        last = base.decision
        footprints = ()
        if last is not None and last.status == "grasp" and missed(base.targets, p.scene):
            g = tuple(float(v) for v in last.grasp)
            gone = gone if g in gone else (gone + (g,))[-self.REMEMBER :]
            footprints = jaw_footprints(g, self._planner.gripper)
        meta = {}
        if gone:
            meta["missed_jaws"] = [r for g in gone for r in jaw_footprints(g, self._planner.gripper)]
        suspects = ()
        if self._spec.loop.wary_neighbours:
            # ... and the objects its jaws may have come down on stay that much farther off.
            suspects = tally_suspects(base.suspects, p.scene, footprints, base.targets)
            if suspects:
                meta["wary"] = wary_outlines(suspects, p.scene)
        scene = dataclasses.replace(p.scene, meta={**p.scene.meta, **meta}) if meta else p.scene
        job = self._worker.submit(
            functools.partial(self._plan, exclude=given_up),
            scene,
            rng,
            base.recent,
            memory if self._spec.loop.remember_failures else None,
            base.unrecognised_grasps < self.MAX_UNRECOGNISED_GRASPS,
            self._spec.pushes.max_per_table - base.pushes,
            t_request=t,
            counter=p.counter,
            info=_Request(base, len(p.scene), scene, misses, gone, suspects, used),
        )
        state.get_mutable_abstract_state(self._job).set_value(Slot(job))

    def _plan(self, scene, rng, avoid, failures, grasp_unrecognised, pushes_left, *, exclude):
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
        )
        return d, rng

    def _raise_lookahead_fault(self, state) -> None:
        """A last lookahead that raised (taken, dropped or still running) re-raises here, in
        the Diagram's thread."""
        last = state.get_mutable_abstract_state(self._last_ahead).get_value().job
        if last is not None and last.future.done() and last.future.exception() is not None:
            last.future.result()

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
