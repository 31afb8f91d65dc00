"""Hardware drivers as LeafSystems, exporting the simulated station's port names.

* UR5 over ur_rtde: the robot's health and joints polled in periodic discrete updates; targets
  streamed with servoJ in periodic publish events, each checked first (joint limits; joint
  speed over the wall-clock time since the last target sent; palm and fingertips inside the
  workspace box; every link frame above the table). A refused target, a lost connection, a
  stale robot state, a stop or a safety mode other than normal latches a fault: the arm is
  stopped, the gripper will not open, and the Diagram halts with a one-line reason.
* Robotiq 2F-85 over the URCap socket (mog_drake.hardware.robotiq): status and fault register
  polled, moves confirmed.
* Cameras: recorded RGB-D frames from disk (offline runs, tests), or an Intel RealSense.

`dry_run`: nothing is sent to the arm or the gripper; every command that would be sent is logged
(JSON lines) and the measured state echoes the command.
"""

from __future__ import annotations

import json
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import EventStatus, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from mog_drake.errors import HardwareFault, MogError
from mog_drake.geometry.gripper import OPEN_WIDTH
from mog_drake.hardware.robotiq import fault_text, move_state
from mog_drake.sim.ur5 import DH_A, DH_ALPHA, DH_D, JOINT_LIMIT, base_transform, dh_transform, palm_in_flange

#: The UR5's DH frames 1..6, by the joint they carry.
LINK_FRAMES = ("shoulder", "elbow", "wrist 1", "wrist 2", "wrist 3", "flange")


class FaultLatch:
    """Shared by the drivers: the first fault wins and stays. Reasons name their device
    (``UR5: ...``, ``gripper: ...``)."""

    def __init__(self):
        self.reason = ""

    def trip(self, reason: str) -> None:
        if not self.reason:
            self.reason = reason

    def __bool__(self) -> bool:
        return bool(self.reason)


# getSafetyMode() and getRobotMode() values of the UR controller (RTDE).
SAFETY_MODES = {
    1: "normal",
    2: "reduced",
    3: "protective stop",
    4: "recovery",
    5: "safeguard stop",
    6: "system emergency stop",
    7: "robot emergency stop",
    8: "violation",
    9: "fault",
    10: "validate joint id",
    11: "undefined safety mode",
    12: "automatic mode safeguard stop",
    13: "system three position enabling stop",
}
SAFETY_OK = (1, 2)  # normal, reduced
ROBOT_MODES = {
    -1: "no controller",
    0: "disconnected",
    1: "confirm safety",
    2: "booting",
    3: "power off",
    4: "power on",
    5: "idle",
    6: "backdrive",
    7: "running",
    8: "updating firmware",
}
ROBOT_RUNNING = 7


@dataclass
class SafetyLimits:
    """What a command must satisfy before it is sent."""

    # Box (xmin, xmax, ymin, ymax, zmin, zmax; m, table frame) the palm and fingertips stay in.
    workspace: list[float] = field(default_factory=lambda: [-0.45, 0.45, -0.45, 0.55, 0.035, 0.65])
    max_joint_speed: float = 1.5  # rad/s, in wall-clock time on hardware
    joint_margin: float = 0.05  # rad inside the +-2 pi limits
    table_top: float = 0.0  # m, z of the table top
    # Every link frame (shoulder, elbow, wrists, flange) at least this far above the table top.
    link_clearance: float = 0.05
    # Optional box every link frame stays in (empty: none).
    link_box: list[float] = field(default_factory=list)
    # Slack of the speed check: the stream may run ahead of max_joint_speed by at most this
    # many seconds of motion at that speed (absorbs the jitter of a non-real-time PC).
    burst_window: float = 0.03


class SafetyMonitor:
    """Checks one joint command against the joint limits and the workspace; returns "" when
    safe, else the reason. (Speed is `MotionBudget`'s: it needs the time between commands.)"""

    def __init__(
        self,
        limits: SafetyLimits,
        base_xyyaw,
        finger_depth: float = 0.040,
        finger_span: float = 0.085,
    ):
        self.limits = limits
        self._base = base_transform(base_xyyaw).GetAsMatrix4()
        self._palm = palm_in_flange().GetAsMatrix4()
        # Fingertips in the palm frame: the plates' centres at the open span, below the palm.
        h = finger_span / 2
        self._tips = np.array([[-h, 0.0, -finger_depth, 1.0], [h, 0.0, -finger_depth, 1.0]]).T

    def frames(self, q) -> dict[str, np.ndarray]:
        """Origins (table frame) of the shoulder, elbow, wrists, flange and palm, and the
        two fingertips."""
        T = self._base.copy()
        out = {}
        for i, name in enumerate(LINK_FRAMES):
            T = T @ dh_transform(q[i], DH_D[i], DH_A[i], DH_ALPHA[i])
            out[name] = T[:3, 3].copy()
        palm = T @ self._palm
        out["palm"] = palm[:3, 3]
        tips = (palm @ self._tips)[:3].T
        out["left fingertip"], out["right fingertip"] = tips[0], tips[1]
        return out

    def palm_position(self, q) -> np.ndarray:
        return self.frames(q)["palm"]

    def check(self, q_cmd) -> str:
        q = np.asarray(q_cmd, float)
        if q.shape != (6,) or not np.all(np.isfinite(q)):
            return f"joint command {q.tolist()} is not six finite numbers"
        lim = JOINT_LIMIT - self.limits.joint_margin
        bad = np.flatnonzero(np.abs(q) > lim)
        if len(bad):
            return f"joint {bad[0] + 1} command {q[bad[0]]:.3f} rad is beyond the limit +-{lim:.3f} rad"
        frames = self.frames(q)
        x0, x1, y0, y1, z0, z1 = self.limits.workspace
        # The palm inside the box; the fingertips inside it in x and y and under its top (their
        # floor is the table top, below).
        for name in ("palm", "left fingertip", "right fingertip"):
            p = frames[name]
            zmin = z0 if name == "palm" else -np.inf
            if not (x0 <= p[0] <= x1 and y0 <= p[1] <= y1 and zmin <= p[2] <= z1):
                return f"{name} at {np.round(p, 3).tolist()} m is outside the workspace box {self.limits.workspace}"
        top = self.limits.table_top
        for name, p in frames.items():
            floor = top if name.endswith("fingertip") or name == "palm" else top + self.limits.link_clearance
            if p[2] < floor:
                return f"{name} at {np.round(p, 3).tolist()} m is {floor - p[2]:.3f} m below its floor z = {floor:.3f} m (the table top {top:g} m)"
        if self.limits.link_box:
            x0, x1, y0, y1, z0, z1 = self.limits.link_box
            for name in LINK_FRAMES:
                p = frames[name]
                if not (x0 <= p[0] <= x1 and y0 <= p[1] <= y1 and z0 <= p[2] <= z1):
                    return f"{name} at {np.round(p, 3).tolist()} m is outside the link box {self.limits.link_box}"
        return ""


class MotionBudget:
    """The speed check, per joint, over the time that really passed (a leaky bucket).

    Each joint earns ``v_max`` rad per second of elapsed time, up to ``v_max * window`` saved,
    and every command spends what it moves. So over any interval [t1, t2] the commands sent
    move a joint by at most ``v_max (t2 - t1) + v_max * window``, whatever their timing: a burst
    of targets (the Simulator catching up with the wall clock), or a jump after a pause, is
    refused once it has used the small saved slack. A command that would overdraw is never sent.
    """

    def __init__(self, v_max: float, window: float):
        self.v_max, self.window = v_max, window
        self.q: np.ndarray | None = None
        self.t = 0.0
        self.saved = np.zeros(6)

    def start(self, q, t: float) -> None:
        self.q, self.t = np.asarray(q, float).copy(), t
        self.saved = np.full(6, self.v_max * self.window)

    def admit(self, q, t: float) -> str:
        """Spends the motion to ``q`` at time ``t`` if the budget allows; else the reason."""
        q = np.asarray(q, float)
        if self.q is None:
            self.start(q, t)
            return ""
        cap = self.v_max * self.window
        saved = np.minimum(self.saved + self.v_max * max(t - self.t, 0.0), cap)
        step = np.abs(q - self.q)
        over = step - saved
        j = int(np.argmax(over))
        if over[j] > 1e-9:
            dt = max(t - self.t, 1e-9)
            return (
                f"joint {j + 1} would move {step[j]:.4f} rad {dt:.4f} s after the last target sent "
                f"({step[j] / dt:.2f} rad/s), above the {self.v_max} rad/s limit"
            )
        self.saved, self.q, self.t = saved - step, q.copy(), t
        return ""


class CommandLog:
    """JSON lines of the commands a dry run would send: to a file (written afresh, its folder
    made), or to stderr without one."""

    def __init__(self, path: str = ""):
        if path:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
        self._f = open(path, "w") if path else sys.stderr  # noqa: SIM115

    def write(self, device: str, t: float, **fields) -> None:
        self._f.write(json.dumps({"device": device, "t": round(t, 4), **fields}) + "\n")
        self._f.flush()

    def close(self) -> None:
        if self._f is not sys.stderr:
            self._f.close()


def robot_health(control, receive) -> str:
    """ "" when both RTDE interfaces are connected and the robot runs in a normal or reduced
    safety mode; else the reason. ur_rtde reports these by value, never by exception."""
    try:
        if not receive.isConnected():
            return "connection lost: the RTDE receive interface is disconnected"
        if not control.isConnected():
            return "connection lost: the RTDE control interface is disconnected"
        if receive.isEmergencyStopped():
            return "emergency stop"
        if receive.isProtectiveStopped():
            return "protective stop"
        mode = int(receive.getSafetyMode())
        if mode not in SAFETY_OK:
            return f"safety mode {mode} ({SAFETY_MODES.get(mode, 'unknown')})"
        robot = int(receive.getRobotMode())
        if robot != ROBOT_RUNNING:
            return f"robot mode {robot} ({ROBOT_MODES.get(robot, 'unknown')}), not running"
    except Exception as e:
        return f"connection lost ({type(e).__name__}: {e})"
    return ""


class UR5Driver(LeafSystem):
    """ur5.position -> servoJ (checked); getActualQ -> ur5.position_measured.

    The driver is the last line of defence and assumes nothing about what is upstream:

    * every target passes `SafetyMonitor` (joint limits, palm and fingertips in the workspace,
      every link frame above the table) and `MotionBudget` (joint speed over the time that
      really passed since the last target sent: the wall clock on hardware, simulated time in
      a dry run). A target that fails is refused, never sent, and latches a fault;
    * each poll reads the robot's health from ur_rtde's own signals, which report by value,
      not by exception: isConnected() of both interfaces, emergency and protective stop, the
      safety mode, the robot mode, and whether the receive timestamp still advances (a lost
      link leaves getActualQ returning its last cached values);
    * servoJ's return value: False is a refusal by the controller, and a fault;
    * on a fault the arm is stopped (servoStop) and the Diagram halts with a one-line reason.

    Targets are streamed every period, changed or not (a servo stream is continuous), with
    servoJ's ``time`` set to the time since the last target sent.
    """

    def __init__(
        self,
        control,
        receive,
        safety: SafetyMonitor,
        faults: FaultLatch,
        q_init,
        period: float = 0.008,
        dry_run: bool = False,
        log: CommandLog | None = None,
        servo=(0.1, 300.0),
        clock=time.monotonic,
        stale_after: float = 0.1,
    ):
        super().__init__()
        self._control, self._receive = control, receive
        self._safety, self._faults = safety, faults
        self._period, self._dry = period, dry_run
        self._log = log or CommandLog()
        self._servo = servo  # lookahead time (s), gain: servoJ's arguments
        self._clock = clock
        self._stale_after = stale_after
        self._budget = MotionBudget(safety.limits.max_joint_speed, safety.limits.burst_window)
        self._cmd = self.DeclareVectorInputPort("ur5.position", 6)
        self._q = self.DeclareDiscreteState(np.asarray(q_init, float))
        # Device bookkeeping (the last target sent, the receive timestamp) lives with the
        # device, not in the Context: it describes the robot, which no Context can rewind.
        self._last = {"q": None, "t": None, "logged": None, "stopped": False}
        self._stamp = {"ts": None, "since": None}
        self.DeclareStateOutputPort("ur5.position_measured", self._q)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._poll)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._send)

    # --- faults and the end of a run -----------------------------------------------------
    def stop(self) -> None:
        """Stops the arm (servoStop), once; safe to call on a lost connection."""
        if self._dry or self._last["stopped"]:
            return
        self._last["stopped"] = True
        try:
            self._control.servoStop()
        except Exception:  # the connection may be what failed
            pass

    def _fail(self, reason: str):
        self._faults.trip(f"UR5: {reason}")
        self.stop()
        return EventStatus.Failed(None, self._faults.reason)

    def health(self) -> str:
        """ "" when the robot is connected, running and its state fresh; else the reason."""
        reason = robot_health(self._control, self._receive)
        if reason:
            return reason
        try:
            ts, now = float(self._receive.getTimestamp()), self._clock()
        except Exception as e:
            return f"connection lost ({type(e).__name__}: {e})"
        if ts != self._stamp["ts"]:
            self._stamp.update(ts=ts, since=now)
        elif now - self._stamp["since"] > self._stale_after:
            return (
                f"robot state is stale: the RTDE timestamp has not advanced for "
                f"{now - self._stamp['since']:.2f} s"
            )
        return ""

    # --- events ---------------------------------------------------------------------------
    def _poll(self, context, discrete_state):
        if self._faults:
            self.stop()
            return EventStatus.Failed(None, self._faults.reason)
        if self._dry:
            if self._last["q"] is not None:
                discrete_state.get_mutable_vector(self._q).SetFromVector(self._last["q"])
            return EventStatus.Succeeded()
        reason = self.health()
        if reason:
            return self._fail(reason)
        try:
            q = np.asarray(self._receive.getActualQ(), float)
        except Exception as e:
            return self._fail(f"connection lost ({type(e).__name__}: {e})")
        if q.shape != (6,) or not np.all(np.isfinite(q)):
            return self._fail(f"getActualQ returned {q.tolist()}, not six finite numbers")
        discrete_state.get_mutable_vector(self._q).SetFromVector(q)
        return EventStatus.Succeeded()

    def _send(self, context):
        if self._faults:
            self.stop()
            return EventStatus.Failed(None, self._faults.reason)
        q = np.asarray(self._cmd.Eval(context), float)
        now = context.get_time() if self._dry else self._clock()
        if self._budget.q is None:
            # The first target is measured against where the arm is.
            self._budget.start(context.get_discrete_state(self._q).value(), now)
        reason = self._safety.check(q) or self._budget.admit(q, now)
        if reason:
            return self._fail(f"refused command: {reason}")
        if self._dry:
            if self._last["logged"] is None or not np.allclose(q, self._last["logged"], atol=1e-6):
                self._log.write("ur5", now, servoJ=[round(v, 5) for v in q])
                self._last["logged"] = q
        else:
            dt = self._period if self._last["t"] is None else now - self._last["t"]
            servo_time = min(max(dt, 0.002), 3 * self._period)
            try:
                ok = self._control.servoJ(q.tolist(), 0.5, 0.5, servo_time, *self._servo)
            except Exception as e:
                return self._fail(f"connection lost ({type(e).__name__}: {e})")
            if not ok:
                return self._fail("servoJ returned False: the controller did not take the target")
        self._last.update(q=q, t=now)
        return EventStatus.Succeeded()


class RobotiqDriver(LeafSystem):
    """gripper.position (inner opening, m) -> moves; status -> gripper.state_measured.

    A changed width is sent as one move (`RobotiqClient.command`, which reads FLT first); each
    poll reads POS, OBJ, FLT and PRE. A fault code, a command the gripper did not take (PRE)
    or a move that does not end within ``move_timeout`` latches a fault. The deadline is the
    move's, not the command's: a new command sent before the move before it ended keeps that
    move's deadline, so a gripper that never ends a move faults however often it is told to
    move. After any fault the jaws never open again: whatever is held stays held.
    """

    def __init__(
        self,
        client,
        faults: FaultLatch,
        force: float,
        speed: float = 0.15,
        period: float = 0.05,
        dry_run: bool = False,
        log: CommandLog | None = None,
        initial_width: float = OPEN_WIDTH,
        move_timeout: float = 5.0,
        clock=time.monotonic,
    ):
        super().__init__()
        self._client, self._faults = client, faults
        self._force, self._speed, self._dry = force, speed, dry_run
        self._log = log or CommandLog()
        self._move_timeout, self._clock = move_timeout, clock
        self._cmd = self.DeclareVectorInputPort("gripper.position", 1)
        self._state = self.DeclareDiscreteState(np.array([initial_width, 0.0]))
        # The last command sent, and when the move under way began (None: no move under way).
        self._sent = {"width": None, "pos": None, "at": None}
        self._holding = False  # the last move ended on an object (OBJ 2) and none followed
        self.lost: list[float] = []  # when a held object was lost (simulated time, s)
        self.DeclareStateOutputPort("gripper.state_measured", self._state)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._poll)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._send)
        self._period = period

    def _fail(self, reason: str):
        self._faults.trip(reason if reason.startswith("gripper:") else f"gripper: {reason}")
        return EventStatus.Failed(None, self._faults.reason)

    def _poll(self, context, discrete_state):
        old = context.get_discrete_state(self._state).value()
        if self._dry:
            w = self._sent["width"] if self._sent["width"] is not None else old[0]
        else:
            try:
                s = self._client.status()
            except MogError as e:
                return self._fail(str(e))
            if s["fault"]:
                return self._fail(fault_text(s["fault"]))
            if self._sent["pos"] is not None and self._sent["at"] is not None:
                done, problem = move_state(
                    s, self._sent["pos"], self._clock() - self._sent["at"], self._move_timeout
                )
                if problem:
                    return self._fail(problem)
                if done:
                    self._sent["at"] = None  # the next command begins a new move
                    self._holding = s["object"] == 2
            if self._holding and self._sent["at"] is None and s["object"] == 3:
                self._holding = False
                self.lost.append(context.get_time())
                warnings.warn(
                    f"gripper: lost what it held at t={context.get_time():.2f} s (OBJ 2 -> 3: the"
                    " fingers closed to the requested width); counted as a drop",
                    stacklevel=1,
                )
            w = s["width"]
        discrete_state.get_mutable_vector(self._state).SetFromVector([w, (w - old[0]) / self._period])
        return EventStatus.Succeeded()

    def _send(self, context):
        w = float(self._cmd.Eval(context)[0])
        if self._sent["width"] is not None and abs(w - self._sent["width"]) < 1e-3:
            return EventStatus.Succeeded()
        if self._faults and (self._sent["width"] is None or w > self._sent["width"]):
            # After a fault the jaws never open: whatever is held stays held.
            return EventStatus.Succeeded()
        if self._dry:
            self._log.write("robotiq", context.get_time(), width=round(w, 4), force=self._force)
        else:
            try:
                pos = self._client.command(w, self._force, self._speed)
            except MogError as e:
                return self._fail(str(e))
            self._sent.update(pos=pos, at=self._sent["at"] if self._sent["at"] is not None else self._clock())
            self._holding = False
        self._sent["width"] = w
        return EventStatus.Succeeded()


def _rgba(rgb: np.ndarray) -> ImageRgba8U:
    h, w = rgb.shape[:2]
    img = ImageRgba8U(w, h)
    img.mutable_data[:, :, :3] = rgb[:, :, :3]
    img.mutable_data[:, :, 3] = 255 if rgb.shape[2] == 3 else rgb[:, :, 3]
    return img


def _depth(depth: np.ndarray) -> ImageDepth32F:
    h, w = depth.shape[:2]
    img = ImageDepth32F(w, h)
    img.mutable_data[:, :, 0] = depth.reshape(h, w)
    return img


def _intrinsics(values, where: str) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) from a sequence of four numbers, focal lengths positive."""
    k = np.asarray(values, float).ravel()
    if k.shape != (4,) or not np.all(np.isfinite(k)) or k[0] <= 0 or k[1] <= 0:
        raise MogError(f"{where}: intrinsics must be (fx, fy, cx, cy) with fx, fy > 0, got {k.tolist()}")
    return tuple(float(v) for v in k)


class ReplayCamera(LeafSystem):
    """Plays recorded RGB-D frames (frame_*.npz with `rgb` uint8, `depth` float32 in m and
    `intrinsics` (fx, fy, cx, cy) of the camera that took them, see `record_frame`), one per
    ``frame_period`` seconds, the last one held. Same ports as the simulated camera; its
    ``intrinsics`` are the frames' own. Frames recorded without intrinsics are read with
    ``fallback_intrinsics`` (the scenario's camera), with a warning; without a fallback they
    are refused."""

    def __init__(self, folder: str, frame_period: float = 1e9, fallback_intrinsics=None):
        super().__init__()
        files = sorted(Path(folder).glob("frame_*.npz"))
        if not files:
            raise MogError(f"no recorded frames (frame_*.npz) in {folder}")
        self._frames = []
        found = set()
        for f in files:
            try:
                d = np.load(f)
                if "rgb" not in d or "depth" not in d:
                    raise MogError(f"{f}: a frame needs arrays 'rgb' and 'depth'")
                rgb, depth = np.asarray(d["rgb"]), np.asarray(d["depth"], np.float32)
                k = _intrinsics(d["intrinsics"], str(f)) if "intrinsics" in d else None
            except MogError:
                raise
            except Exception as e:  # unreadable, truncated, not an npz
                raise MogError(f"{f}: not a readable frame ({type(e).__name__}: {e})") from None
            if rgb.ndim != 3 or rgb.shape[2] not in (3, 4) or depth.shape[:2] != rgb.shape[:2]:
                raise MogError(
                    f"{f}: rgb must be (H, W, 3 or 4) and depth (H, W), got {rgb.shape} and {depth.shape}"
                )
            found.add(k)
            self._frames.append((_rgba(rgb), _depth(depth)))
        if len(found) > 1:
            raise MogError(f"{folder}: the frames were recorded with different intrinsics (or some without)")
        if None in found:
            if fallback_intrinsics is None:
                raise MogError(f"{folder}: frames without intrinsics (record them with record_frame)")
            warnings.warn(
                f"{folder}: frames recorded without intrinsics; using the scenario camera's "
                f"{tuple(round(v, 3) for v in fallback_intrinsics)}",
                stacklevel=2,
            )
        (k,) = found
        self.intrinsics = k or _intrinsics(fallback_intrinsics, "fallback")
        self._period = frame_period
        self.DeclareAbstractOutputPort(
            "camera.rgb_image",
            lambda: AbstractValue.Make(ImageRgba8U()),
            lambda c, o: o.set_value(self._frame(c)[0]),
        )
        self.DeclareAbstractOutputPort(
            "camera.depth_image",
            lambda: AbstractValue.Make(ImageDepth32F()),
            lambda c, o: o.set_value(self._frame(c)[1]),
        )

    def _frame(self, context):
        return self._frames[min(int(context.get_time() / self._period), len(self._frames) - 1)]


def record_frame(folder: str | Path, rgb: np.ndarray, depth: np.ndarray, intrinsics, index: int = 0) -> Path:
    """Writes frame_{index:04d}.npz: rgb, depth (m) and the intrinsics (fx, fy, cx, cy; pixel
    centres at integer coordinates) of the camera that took them, for `ReplayCamera`."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"frame_{index:04d}.npz"
    np.savez_compressed(
        path,
        rgb=np.asarray(rgb)[:, :, :3],
        depth=np.asarray(depth, np.float32).reshape(np.asarray(rgb).shape[:2]),
        intrinsics=np.asarray(_intrinsics(intrinsics, "record_frame")),
    )
    return path


FRAME_TIMEOUT_MS = 2000  # a RealSense that sends no frameset for this long is lost


class _Images:
    """A grabbed (rgb, depth) pair held in abstract state. Drake copies abstract state on every
    unrestricted update, and its images cannot be deep-copied from Python (a tuple of them
    raised TypeError at the first grab); the pair is replaced, never changed, so copies share."""

    def __init__(self, rgb: ImageRgba8U, depth: ImageDepth32F):
        self.rgb, self.depth = rgb, depth

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self


class RealSenseCamera(LeafSystem):
    """An Intel RealSense (pyrealsense2, the `hardware` extra): colour and depth aligned to
    colour, depth in metres. Its ``intrinsics`` are the colour stream's, read from the device
    (the frame depth is aligned to), and depth is scaled by the device's own depth scale. A
    new frame is grabbed at most every ``period`` seconds in a discrete update."""

    def __init__(self, width: int = 640, height: int = 480, fps: int = 30, period: float = 0.1):
        super().__init__()
        try:
            import pyrealsense2 as rs
        except ImportError:
            raise MogError(
                "the RealSense camera needs pyrealsense2: pip install 'mog_drake[hardware]'"
            ) from None
        self._rs = rs
        self._pipe = rs.pipeline()
        cfg = rs.config()
        cfg.enable_stream(rs.stream.color, width, height, rs.format.rgb8, fps)
        cfg.enable_stream(rs.stream.depth, width, height, rs.format.z16, fps)
        profile = self._pipe.start(cfg)
        self._scale = profile.get_device().first_depth_sensor().get_depth_scale()
        # rs2_intrinsics of the colour stream: fx, fy, ppx, ppy in pixels (pixel centres at
        # integer coordinates, as perception reads them), and a distortion model that
        # perception does not undo: a camera whose coefficients are not zero is flagged.
        k = profile.get_stream(rs.stream.color).as_video_stream_profile().get_intrinsics()
        if (k.width, k.height) != (width, height):
            self._pipe.stop()
            raise MogError(
                f"RealSense: colour stream is {k.width} x {k.height}, asked for {width} x {height}"
            )
        self.intrinsics = _intrinsics((k.fx, k.fy, k.ppx, k.ppy), "RealSense")
        if any(abs(c) > 1e-6 for c in k.coeffs):
            warnings.warn(
                f"RealSense: the colour stream has lens distortion {list(k.coeffs)}, which perception "
                "does not undo: expect position errors toward the image corners",
                stacklevel=2,
            )
        self._align = rs.align(rs.stream.color)
        self._images = self.DeclareAbstractState(
            AbstractValue.Make(_Images(ImageRgba8U(width, height), ImageDepth32F(width, height)))
        )
        self.DeclareAbstractOutputPort(
            "camera.rgb_image",
            lambda: AbstractValue.Make(ImageRgba8U()),
            lambda c, o: o.set_value(c.get_abstract_state(self._images).get_value().rgb),
        )
        self.DeclareAbstractOutputPort(
            "camera.depth_image",
            lambda: AbstractValue.Make(ImageDepth32F()),
            lambda c, o: o.set_value(c.get_abstract_state(self._images).get_value().depth),
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._grab)

    def _grab(self, context, state):
        try:
            frames = self._align.process(self._pipe.wait_for_frames(timeout_ms=FRAME_TIMEOUT_MS))
        except RuntimeError as e:  # librealsense: "Frame didn't arrive within ..."
            raise HardwareFault(f"camera: no frame within {FRAME_TIMEOUT_MS / 1000:g} s ({e})") from None
        rgb = np.asanyarray(frames.get_color_frame().get_data())
        depth = np.asanyarray(frames.get_depth_frame().get_data()).astype(np.float32) * self._scale
        depth[depth == 0] = np.nan
        state.get_mutable_abstract_state(self._images).set_value(_Images(_rgba(rgb), _depth(depth)))
