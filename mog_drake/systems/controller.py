"""The Controller system: executes pick decisions on the station's arm and gripper ports (see
`mog_drake.systems.perception` for how the three application systems talk)."""

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from mog_drake.config import ControllerConfig
from mog_drake.errors import MogError
from mog_drake.geometry.gripper import OPEN_WIDTH
from mog_drake.geometry.polygon import convex_hull_ccw
from mog_drake.geometry.push import Push
from mog_drake.systems.messages import Checked, Decision, Immutable, Perceived


@dataclass
class ControllerState(Immutable):
    """Replaced by a new value on every change (``attempts`` is a new list of new dicts)."""

    mode: str = "settle"
    t_mode: float = 0.0
    counter: int = 0  # the request whose decision the arm waits for, or executes
    requested: int = 0  # the newest image requested (counter + 1 once the next one is taken)
    check: int = 0  # the request whose image the table is checked against at the observe pose
    q_hold: np.ndarray = field(default_factory=lambda: np.zeros(6))
    gripper: float = OPEN_WIDTH
    plan: dict | None = None
    attempts: list = field(default_factory=list)
    # Grasps the arm could not reach, in order: {"t", "grasp", "reason", "planning_time"}.
    skipped: list = field(default_factory=list)
    unreachable: int = 0  # unreachable grasps in a row
    finished: str = ""
    # Simulated time (s): the arm moving or the gripper acting; the arm idle waiting for a
    # scene and for a decision; the first request and the end.
    robot_time: float = 0.0
    wait_perception: float = 0.0
    wait_planning: float = 0.0
    t_first: float | None = None
    t_end: float | None = None
    t_last: float = 0.0
    retakes: int = 0  # decisions dropped because the table changed after their image
    # push-mog: the pushes made, in order ({"start", "end", "push", "group", "expected",
    # "now"}), and the robot time they took (s).
    pushes: list = field(default_factory=list)
    push_time: float = 0.0
    # The wrist's force (N, world frame) as the descent began: what the guard measures from.
    force_zero: np.ndarray | None = None


class ControllerSystem(LeafSystem):
    """A state machine per attempt: ask for a grasp, move above it, descend (guarded: past
    ``config.guard_force`` on the wrist the arm backs out, the attempt stopped), close with the
    force limit, lift, move above the bin, open, return to the observe pose, ask again.
    ``close_time``: how long the jaws close (see ControllerConfig.close_margin).

    The next image is asked for as soon as, after the grasp, the arm hides none of the
    objects left on the table and what it carries hangs above what perception looks at
    (`ArmView`), or at the latest when the jaws open over the bin: then the objects carried
    are over the bin, which perception ignores, and what the arm still hides of the table is
    checked at the observe pose. The next decision is
    planned while the arm drops and returns. At the observe pose the controller asks
    Perception to check that the table has not changed since that image; if it has (an object
    dropped in transit, one moved by the lift, one found where the arm hid it), the decision
    is dropped and a new image taken there.

    Unless ``config.return_home``, the arm does not return: where, with the jaws open over
    the bin, it hides none of the table (`ArmView`), the check is made from there and the next
    grasp or push starts from the bin. A push still ends at the observe pose, out of the
    image of the table it leaves."""

    MOTIONS = {
        "approach": "close",
        "retreat": "observe",  # a descent stopped on an object (guard_force): back up and out
        "lift": "to_bin",
        "to_bin": "open",
        "home": "observe",
        # push-mog: down beside the object with the jaws closed, along the line, up and back
        "push_approach": "push_line",
        "push_line": "push_up",
        "push_up": "push_home",  # or, with a grasp to follow at once, "push_open"
        "push_home": "wait",
    }

    def __init__(
        self,
        motion,
        home,
        bin_xy,
        bin_height: float,
        open_width: float = OPEN_WIDTH,
        close_time: float = 0.45,
        *,
        time_limit: float = 600.0,
        config: ControllerConfig | None = None,
        arm_view=None,
        push_speed: float = 0.05,
    ):
        super().__init__()
        cfg = config or ControllerConfig()
        self._motion = motion
        self._home = np.asarray(home, float)
        self._bin = (bin_xy, bin_height)
        self._open = open_width
        self._close_time, self._open_time, self._settle = close_time, cfg.open_time, cfg.settle_time
        self._max_unreachable = cfg.max_unreachable
        self._return_home = cfg.return_home
        self._guard = cfg.guard_force
        period = cfg.period
        self._limit = time_limit
        self._arm_view = arm_view
        self._push_speed = push_speed
        self._q = self.DeclareVectorInputPort("ur5.position_measured", 6)
        self._g = self.DeclareVectorInputPort("gripper.state_measured", 2)
        self._f = self.DeclareVectorInputPort("ur5.wrist_force", 3)
        self._decision = self.DeclareAbstractInputPort("decision", AbstractValue.Make(Decision()))
        self._scene = self.DeclareAbstractInputPort("scene", AbstractValue.Make(Perceived()))
        self._checked = self.DeclareAbstractInputPort("checked", AbstractValue.Make(Checked()))
        self._state = self.DeclareAbstractState(AbstractValue.Make(ControllerState(q_hold=self._home.copy())))
        # Outputs read state (and time) only: no feedthrough from the inputs.
        only_state = {self.all_state_ticket(), self.time_ticket()}
        self.DeclareVectorOutputPort("ur5.position", 6, self._out_q, prerequisites_of_calc=only_state)
        self.DeclareVectorOutputPort("gripper.position", 1, self._out_g, prerequisites_of_calc=only_state)
        self.DeclareVectorOutputPort("request", 1, self._out_req, prerequisites_of_calc=only_state)
        self.DeclareVectorOutputPort(
            "check", 1, lambda c, o: o.SetFromVector([self.state(c).check]), prerequisites_of_calc=only_state
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)

    def state(self, context) -> ControllerState:
        return context.get_abstract_state(self._state).get_value()

    def _update(self, context, state) -> None:
        s = self.state(context)
        t = context.get_time()
        new = ControllerState(**{**s.__dict__, "attempts": list(s.attempts), "pushes": list(s.pushes)})
        dt = t - s.t_mode
        if s.mode == "done":
            return
        self._count_time(context, s, new, t)
        if s.mode == "push_home" and s.requested == s.counter and self._image_now(context, s, holding=False):
            new.requested = s.counter + 1  # the pushed table, as soon as the arm is out of view
            new.pushes[-1] = {**new.pushes[-1], "next_image": [s.mode, round(dt, 3)]}
        if s.mode in ("lift", "to_bin", "open", "home") and s.requested == s.counter:
            if s.mode in ("open", "home") or self._image_now(context, s):
                new.requested = s.counter + 1  # the next image, while the arm carries
                if new.attempts:  # when, in the attempt: the moment the next plan could start
                    new.attempts[-1] = {**new.attempts[-1], "next_image": [s.mode, round(dt, 3)]}
        if t >= self._limit and s.mode in ("observe", "wait", "settle", "check"):
            new.mode, new.finished = "done", "time limit"
            if s.mode == "wait":  # say what it was waiting for: a run that planned nothing in
                # its time did not end well, whatever it picked (none of it, maybe)
                seen = self._scene.Eval(context).counter >= s.counter
                new.finished += ", waiting for planning" if seen else ", waiting for perception"
        elif s.mode == "settle" and dt >= self._settle:
            new.mode, new.t_mode, new.t_first = "wait", t, t
            new.counter = new.requested = s.counter + 1
        elif s.mode == "observe":
            new.mode, new.t_mode = "wait", t
            new.counter = new.requested = s.requested + 1
        elif s.mode == "check":
            c = self._checked.Eval(context)
            if c.counter == s.check:
                new.mode, new.t_mode = "wait", t
                if c.changed:  # drop its decision: a new image here
                    new.counter = new.requested = s.check + 1
                    new.retakes = s.retakes + 1
                else:
                    new.counter = s.check
        elif s.mode == "wait":
            d = self._decision.Eval(context)
            if d.counter == s.counter and d.decision is not None:
                dec = d.decision
                if dec.status == "push":
                    self._start_push(new, s, d, t)
                elif dec.status != "grasp":
                    new.mode, new.finished = "done", dec.status
                else:
                    self._start_grasp(new, s, d, t)
        elif (
            s.mode == "approach"
            and self._guard > 0
            and dt >= s.plan["descend_at"]
            and self._stopped(context, s, new, t)
        ):
            pass  # the descent met an object: backing out (`_stopped`)
        elif s.mode in self.MOTIONS:
            if dt >= s.plan[s.mode].end_time() + 0.05:
                self._motion_done(new, s, t)
        elif s.mode == "close" and dt >= self._close_time:
            new.attempts[-1] = {**new.attempts[-1], "held_width": float(self._g.Eval(context)[0])}
            new.mode, new.t_mode = "lift", t
        elif s.mode == "open" and dt >= self._open_time:
            new.mode, new.t_mode = "home", t
            if self._from_bin(context, new):
                self._end_attempt(new, s, t)
        elif s.mode == "push_open" and dt >= self._open_time:
            self._grasp_after_push(new, s, t)
        if s.mode == "to_bin" and new.mode == "open":
            new.gripper = self._open
        if new.mode == "done" and s.mode != "done":
            new.t_end = t
        state.get_mutable_abstract_state(self._state).set_value(new)

    def _stopped(self, context, s: ControllerState, new: ControllerState, t: float) -> bool:
        """The guarded descent: the wrist's force is measured from its value as the descent
        began; past ``guard_force`` the plate has come down on something the planner did not
        see there (an object where perception put none): the arm stops and backs out the way it
        came, the jaws still open, and the attempt ends there (``stopped``). A real arm pressed
        on would otherwise reach its own force limit and protective-stop."""
        f = np.asarray(self._f.Eval(context), float)
        if s.force_zero is None:
            new.force_zero = f
            return False
        push = float(np.linalg.norm(f - s.force_zero))
        if push <= self._guard:
            return False
        dt = t - s.t_mode
        q_now = s.plan["approach"].value(min(dt, s.plan["approach"].end_time())).ravel()
        new.plan = {**s.plan, "retreat": self._motion.retreat(q_now, s.plan["above"], self._home)}
        new.mode, new.t_mode = "retreat", t
        new.attempts[-1] = {**new.attempts[-1], "stopped": {"force": round(push, 1), "after": round(dt, 3)}}
        return True

    def _count_time(self, context, s: ControllerState, new: ControllerState, t: float) -> None:
        """The interval since the last update, by what the arm did in it."""
        step, new.t_last = t - s.t_last, t
        if s.t_first is None:
            return
        if s.mode in self.MOTIONS or s.mode in ("close", "open", "push_open"):
            new.robot_time += step
            if s.mode.startswith("push"):
                new.push_time += step
        elif s.mode in ("wait", "check"):
            waiting_for = s.check if s.mode == "check" else s.counter
            if self._scene.Eval(context).counter < waiting_for:
                new.wait_perception += step
            else:
                new.wait_planning += step

    def _start_grasp(self, new: ControllerState, s: ControllerState, d, t: float) -> None:
        """Decision ``d``'s grasp: its motions planned and an attempt begun, or skipped if
        the arm cannot reach it (observe again: the planner does not repeat its last grasps)."""
        dec = d.decision
        try:
            new.plan = self._motion.pick_plan(dec.grasp, s.q_hold, *self._bin, q_home=self._home)
        except MogError as e:
            self._skip(new, s, d, t, "grasp", dec.grasp.tolist(), e=e)
            return
        new.mode, new.t_mode, new.unreachable, new.force_zero = "approach", t, 0, None
        new.attempts.append(
            {
                "start": t,
                "group": list(dec.group),
                "shapes": list(dec.shapes),
                "grasp": dec.grasp.tolist(),
                "planning_time": dec.planning_time,
                "planning_cpu": d.cpu_time,
                "objects_seen": d.objects_seen,
                **({"blobs_seen": d.blobs_seen} if d.blobs_seen else {}),
                "physics_checks": dec.physics_checks,
                "expected": list(dec.expected),
                # Groups replayed from memory, and whether the lookahead's memory was in time
                # for this plan (see PlannerSystem).
                "remembered": dec.remembered,
                "lookahead": d.lookahead,
                **({"unrecognised": True} if dec.unrecognised else {}),
                **({"lone": dec.lone} if dec.lone else {}),
                # Found by the last resort: a robust planner's screen and samples relaxed.
                **({"last_resort": True} if dec.last_resort else {}),
                **({"relaxed": True} if dec.relaxed else {}),
            }
        )

    def _motion_done(self, new: ControllerState, s: ControllerState, t: float) -> None:
        """The motion of mode ``s.mode`` has ended: on to the next mode."""
        traj = s.plan[s.mode]
        new.q_hold = traj.value(traj.end_time()).ravel()
        new.mode, new.t_mode = self.MOTIONS[s.mode], t
        if s.mode == "approach":
            new.gripper = 0.0
        if s.mode == "push_up" and s.plan.get("then") is not None:
            new.mode, new.gripper = "push_open", self._open  # open above the objects
            new.pushes[-1] = {**new.pushes[-1], "end": t}
        if s.mode == "push_home":  # open the jaws, and a new image of the pushed table
            new.gripper = self._open
            new.pushes[-1] = {**new.pushes[-1], "end": t}
            new.plan = None
            new.counter = new.requested = new.requested if new.requested > s.counter else s.counter + 1
        if s.mode in ("home", "retreat"):
            self._end_attempt(new, s, t)

    def _from_bin(self, context, new: ControllerState) -> bool:
        """Whether the arm, its jaws open over the bin, goes on from there (not
        ``return_home``, the next image taken, and the arm hiding none of the table)."""
        if self._return_home or self._arm_view is None or new.requested == new.counter:
            return False
        return bool(self._arm_view(self._q.Eval(context), holding=False))

    def _end_attempt(self, new: ControllerState, s: ControllerState, t: float) -> None:
        """The attempt ends where the arm is (the observe pose, or over the bin): the table is
        checked against the image taken on the way, or, with none taken, imaged here."""
        new.attempts[-1] = {**new.attempts[-1], "end": t}
        new.plan = None
        if new.requested == s.counter:  # no image on the way: one here
            new.mode = "wait"
            new.counter = new.requested = s.counter + 1
        else:
            new.mode, new.check = "check", new.requested

    def _skip(self, new: ControllerState, s: ControllerState, d, t: float, kind: str, what, *, e) -> None:
        """Skips decision ``d``'s grasp or push (``kind``), which the arm cannot reach: logged,
        and the arm observes again; max_unreachable in a row end the run."""
        entry = {"t": t, kind: what, "reason": str(e), "planning_time": d.decision.planning_time}
        new.skipped = [*s.skipped, {**entry, "planning_cpu": d.cpu_time}]
        new.unreachable = s.unreachable + 1
        new.mode, new.t_mode = "observe", t
        if new.unreachable >= self._max_unreachable:
            new.mode, new.finished = "done", f"unreachable {kind} ({new.unreachable} in a row): {e}"

    def _grasp_after_push(self, new: ControllerState, s: ControllerState, t: float) -> None:
        """After a push, with the jaws open above the objects: the grasp of the group it set
        up, where the planner's physics check left it (no new image), back to the observe
        pose after the bin; or, the arm unable to reach it, back to the observe pose."""
        dec = s.plan["then"]
        try:
            plan = self._motion.pick_plan(dec.grasp, s.q_hold, *self._bin, q_home=self._home)
        except MogError:
            new.plan = {"push_home": self._motion.timed([s.q_hold, self._home])}
            new.mode, new.t_mode = "push_home", t
            return
        new.plan, new.mode, new.t_mode, new.force_zero = plan, "approach", t, None
        new.attempts.append(
            {
                "start": t,
                "group": list(dec.group),
                "shapes": list(dec.shapes),
                "grasp": dec.grasp.tolist(),
                "planning_time": 0.0,  # the push's decision planned it
                "planning_cpu": 0.0,
                "objects_seen": s.pushes[-1].get("objects_seen", 0),
                "physics_checks": 0,
                "expected": list(dec.expected),
                "after_push": True,
            }
        )

    def _start_push(self, new: ControllerState, s: ControllerState, d, t: float) -> None:
        """Starts the push of decision ``d`` (the jaws close on the way), or skips it as an
        unreachable grasp is skipped. A push decision with a grasp (planner.pushes.then_grasp)
        grasps the group it set up at once, without a new image."""
        dec = d.decision
        try:
            new.plan = self._motion.push_plan(dec.push, s.q_hold, self._push_speed, q_home=self._home)
            new.plan["then"] = dec if dec.grasp is not None else None
        except MogError as e:
            self._skip(new, s, d, t, "push", dec.push.to_dict(), e=e)
            return
        new.mode, new.t_mode, new.unreachable, new.gripper = "push_approach", t, 0, 0.0
        new.pushes.append(
            {
                "start": t,
                "push": dec.push.to_dict(),
                "group": list(dec.group),
                "shapes": list(dec.shapes),
                "expected": list(dec.expected),
                "now": dec.now,
                "planning_time": dec.planning_time,
                "planning_cpu": d.cpu_time,
                "physics_checks": dec.physics_checks,
                "objects_seen": d.objects_seen,
                "remembered": dec.remembered,
                "remembered_pushes": dec.remembered_pushes,
                "lookahead": d.lookahead,
            }
        )

    def _image_now(self, context, s: ControllerState, holding: bool = True) -> bool:
        """Whether the next image may be taken now, while the arm still carries: it hides
        nothing of the table, or at least none of the objects left on it (the last scene's,
        less the group being carried), and what it carries hangs above what perception looks
        at. Anything else that moved is the observe pose's check's to find."""
        if self._arm_view is None:
            return False
        q = self._q.Eval(context)
        if self._arm_view(q, holding=holding):
            return True
        scene = self._scene.Eval(context).scene
        if scene is None:
            return False
        carried = set(s.attempts[-1]["group"]) if s.attempts and holding else set()
        prisms = [(scene.polygon(i), scene.shape(i).height) for i in range(len(scene)) if i not in carried]
        prisms += [(b["vertices"], b["top"]) for b in scene.meta.get("unrecognised", ())]
        if not holding and s.pushes:  # the pushed object: anywhere along its push
            p = Push(**s.pushes[-1]["push"])
            if 0 <= p.target < len(scene):
                v = scene.polygon(p.target)
                swept = np.vstack([v, v + p.direction * (p.distance + 0.01)])
                prisms.append((convex_hull_ccw(swept), scene.shape(p.target).height))
        return self._arm_view.clear_of(q, holding, prisms)

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
        output.SetFromVector([self.state(context).requested])
