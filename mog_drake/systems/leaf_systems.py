"""Perception, Planner and Controller: the pick-and-place application as Drake LeafSystems.

They talk through request counters, so each expensive step runs once per request in a periodic
unrestricted update, and every output only reads state:

    Controller.request (k) -> Perception (renders, perceives once for k) -> scene (k)
    -> Planner (Alg. 1 once for k) -> decision (k) -> Controller (executes, then asks k+1)

None of them reads the plant's ground truth: Perception sees only the camera images.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from mog_drake.errors import MogError
from mog_drake.geometry import DEFAULT_GROUP_RADIUS
from mog_drake.perception import Perceiver
from mog_drake.planning.picking import PickDecision, next_pick


class _Immutable:
    """State values that are replaced, never changed in place. Drake copies abstract state
    (every unrestricted update copies the whole state); a deep copy of a perceived Scene or a
    motion plan per 10 ms tick cost a third of a pick run's wall time, so copies share."""

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self


@dataclass
class Perceived(_Immutable):
    counter: int = -1
    scene: object = None
    wall_time: float = 0.0


@dataclass
class Decision(_Immutable):
    counter: int = -1
    decision: PickDecision | None = None
    objects_seen: int = 0
    recent: tuple = ()  # the last grasps issued, not to be repeated
    failures: tuple = ()  # groups found to have no grasp (see next_pick)
    unrecognised_grasps: int = 0  # grasps of unrecognised blobs issued in a row


class PerceptionSystem(LeafSystem):
    """camera.rgb_image, camera.depth_image, request -> scene (a perceived Scene).
    ``perceiver``: what turns the images into a scene (e.g. `Scenario.perceiver`)."""

    def __init__(self, camera, perceiver: Perceiver, period: float = 0.01):
        super().__init__()
        self._perceiver = perceiver
        self._X_WC = camera.X_WC().GetAsMatrix4()
        self._K = camera.intrinsics()
        self._rgb = self.DeclareAbstractInputPort("camera.rgb_image", AbstractValue.Make(ImageRgba8U()))
        self._depth = self.DeclareAbstractInputPort("camera.depth_image", AbstractValue.Make(ImageDepth32F()))
        self._request = self.DeclareVectorInputPort("request", 1)
        self._state = self.DeclareAbstractState(AbstractValue.Make(Perceived()))
        self.DeclareAbstractOutputPort(
            "scene",
            lambda: AbstractValue.Make(Perceived()),
            self._out,
            prerequisites_of_calc={self.all_state_ticket()},
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)

    def _update(self, context, state) -> None:
        req = int(self._request.Eval(context)[0])
        cur = context.get_abstract_state(self._state).get_value()
        if req <= cur.counter:
            return
        t0 = time.perf_counter()
        rgb = self._rgb.Eval(context).data
        depth = self._depth.Eval(context).data[:, :, 0]
        scene = self._perceiver.perceive(rgb, depth, self._X_WC, self._K, seed=req)
        state.get_mutable_abstract_state(self._state).set_value(
            Perceived(req, scene, time.perf_counter() - t0)
        )

    def _out(self, context, output) -> None:
        output.set_value(context.get_abstract_state(self._state).get_value())


class PlannerSystem(LeafSystem):
    """scene -> decision: Alg. 1 (mog) or the single-object baseline (sog) once per new scene."""

    REMEMBER = 3  # grasps not to repeat: the last three issued
    # Grasps of unrecognised blobs in a row before the run ends on them: each failed one moves
    # the blob, so the planner would otherwise try a new outline until the time limit.
    MAX_UNRECOGNISED_GRASPS = 3

    def __init__(
        self,
        planner,
        mode: str = "mog",
        seed: int = 0,
        period: float = 0.01,
        partial_lifts: bool = True,
        remember_failures: bool = True,
        group_radius: float = DEFAULT_GROUP_RADIUS,
        last_resort: bool = True,
        grouping: str = "radius",
    ):
        super().__init__()
        self._planner = planner
        self._group_radius = group_radius
        self._grouping = grouping
        self._last_resort = last_resort
        self._remember = remember_failures
        self._mode = mode
        self._partial_lifts = partial_lifts
        self._rng = np.random.default_rng(seed)
        self._scene = self.DeclareAbstractInputPort("scene", AbstractValue.Make(Perceived()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(Decision()))
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
        d = next_pick(
            p.scene,
            self._planner,
            self._mode,
            self._rng,
            partial_lifts=self._partial_lifts,
            avoid=cur.recent,
            failures=cur.failures if self._remember else None,
            group_radius=self._group_radius,
            grouping=self._grouping,
            grasp_unrecognised=cur.unrecognised_grasps < self.MAX_UNRECOGNISED_GRASPS,
            last_resort=self._last_resort,
        )
        recent = cur.recent + ((tuple(float(v) for v in d.grasp),) if d.grasp is not None else ())
        if d.status == "grasp":
            blob_grasps = cur.unrecognised_grasps + 1 if d.unrecognised else 0
        else:  # a clear table, or given up: the count stands
            blob_grasps = cur.unrecognised_grasps
        state.get_mutable_abstract_state(self._state).set_value(
            Decision(p.counter, d, len(p.scene), recent[-self.REMEMBER :], d.failures, blob_grasps)
        )

    def _out(self, context, output) -> None:
        output.set_value(context.get_abstract_state(self._state).get_value())


@dataclass
class ControllerState(_Immutable):
    """Replaced by a new value on every change (``attempts`` is a new list of new dicts)."""

    mode: str = "settle"
    t_mode: float = 0.0
    counter: int = 0
    q_hold: np.ndarray = field(default_factory=lambda: np.zeros(6))
    gripper: float = 0.075
    plan: dict | None = None
    attempts: list = field(default_factory=list)
    # Grasps the arm could not reach, in order: {"t", "grasp", "reason", "planning_time"}.
    skipped: list = field(default_factory=list)
    unreachable: int = 0  # unreachable grasps in a row
    finished: str = ""


class ControllerSystem(LeafSystem):
    """A state machine per attempt: ask for a grasp, move above it, descend, close with the
    force limit, lift, move above the bin, open, return to the observe pose, ask again."""

    MAX_UNREACHABLE = 3  # unreachable grasps in a row that end the run
    MOTIONS = {"approach": "close", "lift": "to_bin", "to_bin": "open", "home": "observe"}

    def __init__(
        self,
        motion,
        home,
        bin_xy,
        bin_height: float,
        open_width: float = 0.075,
        close_time: float = 0.45,
        open_time: float = 0.35,
        settle_time: float = 0.2,
        time_limit: float = 600.0,
        period: float = 0.01,
    ):
        super().__init__()
        self._motion = motion
        self._home = np.asarray(home, float)
        self._bin = (bin_xy, bin_height)
        self._open = open_width
        self._close_time, self._open_time, self._settle = close_time, open_time, settle_time
        self._limit = time_limit
        self._q = self.DeclareVectorInputPort("ur5.position_measured", 6)
        self._g = self.DeclareVectorInputPort("gripper.state_measured", 2)
        self._decision = self.DeclareAbstractInputPort("decision", AbstractValue.Make(Decision()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(ControllerState(q_hold=self._home.copy())))
        # Outputs read state (and time) only: no feedthrough from the inputs.
        only_state = {self.all_state_ticket(), self.time_ticket()}
        self.DeclareVectorOutputPort("ur5.position", 6, self._out_q, prerequisites_of_calc=only_state)
        self.DeclareVectorOutputPort("gripper.position", 1, self._out_g, prerequisites_of_calc=only_state)
        self.DeclareVectorOutputPort("request", 1, self._out_req, prerequisites_of_calc=only_state)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)

    def state(self, context) -> ControllerState:
        return context.get_abstract_state(self._state).get_value()

    def _update(self, context, state) -> None:
        s = self.state(context)
        t = context.get_time()
        new = ControllerState(**{**s.__dict__, "attempts": list(s.attempts)})
        dt = t - s.t_mode
        if s.mode == "done":
            return
        if t >= self._limit and s.mode in ("observe", "wait", "settle"):
            new.mode, new.finished = "done", "time limit"
        elif s.mode == "settle" and dt >= self._settle:
            new.mode, new.counter, new.t_mode = "wait", s.counter + 1, t
        elif s.mode == "observe":
            new.mode, new.counter, new.t_mode = "wait", s.counter + 1, t
        elif s.mode == "wait":
            d = self._decision.Eval(context)
            if d.counter == s.counter and d.decision is not None:
                dec = d.decision
                if dec.status != "grasp":
                    new.mode, new.finished = "done", dec.status
                else:
                    try:
                        new.plan = self._motion.pick_plan(dec.grasp, s.q_hold, *self._bin)
                    except MogError as e:
                        # Observe again: the planner does not repeat its last few grasps.
                        new.skipped = [
                            *s.skipped,
                            {
                                "t": t,
                                "grasp": dec.grasp.tolist(),
                                "reason": str(e),
                                "planning_time": dec.planning_time,
                            },
                        ]
                        new.unreachable = s.unreachable + 1
                        new.mode, new.t_mode = "observe", t
                        if new.unreachable >= self.MAX_UNREACHABLE:
                            new.mode = "done"
                            new.finished = f"unreachable grasp ({new.unreachable} in a row): {e}"
                    else:
                        new.mode, new.t_mode, new.unreachable = "approach", t, 0
                        new.attempts.append(
                            {
                                "start": t,
                                "group": list(dec.group),
                                "grasp": dec.grasp.tolist(),
                                "planning_time": dec.planning_time,
                                "objects_seen": d.objects_seen,
                                "physics_checks": dec.physics_checks,
                                "expected": list(dec.expected),
                                **({"unrecognised": True} if dec.unrecognised else {}),
                            }
                        )
        elif s.mode in self.MOTIONS:
            traj = s.plan[s.mode]
            if dt >= traj.end_time() + 0.05:
                new.q_hold = traj.value(traj.end_time()).ravel()
                new.mode, new.t_mode = self.MOTIONS[s.mode], t
                if s.mode == "approach":
                    new.gripper = 0.0
                if s.mode == "home":
                    new.attempts[-1] = {**new.attempts[-1], "end": t}
                    new.plan = None
        elif s.mode == "close" and dt >= self._close_time:
            new.attempts[-1] = {**new.attempts[-1], "held_width": float(self._g.Eval(context)[0])}
            new.mode, new.t_mode = "lift", t
        elif s.mode == "open" and dt >= self._open_time:
            new.mode, new.t_mode = "home", t
        if s.mode == "to_bin" and new.mode == "open":
            new.gripper = self._open
        state.get_mutable_abstract_state(self._state).set_value(new)

    def _out_q(self, context, output) -> None:
        s = self.state(context)
        if s.mode in self.MOTIONS and s.plan is not None:
            traj = s.plan[s.mode]
            output.SetFromVector(traj.value(min(context.get_time() - s.t_mode, traj.end_time())).ravel())
        else:
            output.SetFromVector(s.q_hold)

    def _out_g(self, context, output) -> None:
        output.SetFromVector([self.state(context).gripper])

    def _out_req(self, context, output) -> None:
        output.SetFromVector([self.state(context).counter])
