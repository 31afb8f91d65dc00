"""The Planner system: a perceived Scene in, a pick decision out (see `mog_drake.systems.perception`
for how the three application systems talk)."""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from mog_drake.planning.config import PlannerSpec
from mog_drake.planning.picking import PickDecision, next_pick
from mog_drake.systems.perception import Perceived, _Immutable


@dataclass
class Decision(_Immutable):
    counter: int = -1
    decision: PickDecision | None = None
    objects_seen: int = 0
    recent: tuple = ()  # the last grasps issued, not to be repeated
    failures: tuple = ()  # groups found to have no grasp (see next_pick)
    unrecognised_grasps: int = 0  # grasps of unrecognised blobs issued in a row
    rng: np.random.Generator | None = None  # the planner's random draws, after this decision


class PlannerSystem(LeafSystem):
    """scene -> decision: Alg. 1 (mog) or the single-object baseline (sog) once per new scene,
    as ``spec`` (`PlannerSpec`) says, with ``planner`` (a GraspPlanner). The random draws come
    from a Generator seeded with ``spec.seed`` that lives in the Context's state."""

    REMEMBER = 3  # grasps not to repeat: the last three issued
    # Grasps of unrecognised blobs in a row before the run ends on them: each failed one moves
    # the blob, so the planner would otherwise try a new outline until the time limit.
    MAX_UNRECOGNISED_GRASPS = 3

    def __init__(self, planner, spec: PlannerSpec | None = None, period: float = 0.01):
        super().__init__()
        self._planner = planner
        self._spec = spec or PlannerSpec()
        self._spec.check()
        self._scene = self.DeclareAbstractInputPort("scene", AbstractValue.Make(Perceived()))
        self._state = self.DeclareAbstractState(
            AbstractValue.Make(Decision(rng=np.random.default_rng(self._spec.seed)))
        )
        self.DeclareAbstractOutputPort(
            "decision",
            lambda: AbstractValue.Make(Decision()),
            self._out,
            prerequisites_of_calc={self.all_state_ticket()},
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)

    def _update(self, context, state) -> None:
        p = self._scene.Eval(context)
        cur = context.get_abstract_state(self._state).get_value()
        if p.scene is None or p.counter <= cur.counter:
            return
        rng = copy.deepcopy(cur.rng)  # the state's value is never changed in place
        d = next_pick(
            p.scene,
            self._planner,
            self._spec,
            rng,
            avoid=cur.recent,
            failures=cur.failures if self._spec.remember_failures else None,
            grasp_unrecognised=cur.unrecognised_grasps < self.MAX_UNRECOGNISED_GRASPS,
        )
        recent = cur.recent + ((tuple(float(v) for v in d.grasp),) if d.grasp is not None else ())
        if d.status == "grasp":
            blob_grasps = cur.unrecognised_grasps + 1 if d.unrecognised else 0
        else:  # a clear table, or given up: the count stands
            blob_grasps = cur.unrecognised_grasps
        state.get_mutable_abstract_state(self._state).set_value(
            Decision(p.counter, d, len(p.scene), recent[-self.REMEMBER :], d.failures, blob_grasps, rng)
        )

    def _out(self, context, output) -> None:
        output.set_value(context.get_abstract_state(self._state).get_value())
