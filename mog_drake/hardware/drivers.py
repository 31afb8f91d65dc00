"""Hardware drivers as LeafSystems, exporting the simulated station's port names.

* UR5 over ur_rtde: measured joints polled in periodic discrete updates; commands streamed with
  servoJ in periodic publish events, each checked first (joint limits, joint speed, the palm
  inside a workspace box). A refused command, a lost connection or a protective stop latches a
  fault: the arm is stopped, the gripper will not open, and the Diagram halts with the reason.
* Robotiq 2F-85 over the URCap socket (mog_drake.hardware.robotiq).
* Cameras: recorded RGB-D frames from disk (offline runs, tests), or an Intel RealSense.

`dry_run`: nothing is sent to the arm or the gripper; every command that would be sent is logged
(JSON lines) and the measured state echoes the command.
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import EventStatus, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from mog_drake.errors import MogError
from mog_drake.sim.ur5 import JOINT_LIMIT, forward_kinematics


class FaultLatch:
    """Shared by the drivers: the first fault wins and stays."""

    def __init__(self):
        self.reason = ""

    def trip(self, reason: str) -> None:
        if not self.reason:
            self.reason = reason

    def __bool__(self) -> bool:
        return bool(self.reason)


@dataclass
class SafetyLimits:
    """What a command must satisfy before it is sent."""

    workspace: list[float] = field(
        default_factory=lambda: [-0.45, 0.45, -0.45, 0.55, 0.035, 0.65]
    )  # palm box, m
    max_joint_speed: float = 1.5  # rad/s
    joint_margin: float = 0.05  # rad inside the +-2 pi limits


class SafetyMonitor:
    """Checks joint commands; returns "" when safe, else the reason."""

    def __init__(self, limits: SafetyLimits, base_xyyaw, flange_to_palm: float):
        self.limits = limits
        bx, by, byaw = base_xyyaw
        c, s = math.cos(byaw), math.sin(byaw)
        self._base = np.array([[c, -s, 0, bx], [s, c, 0, by], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        self._palm = np.array([[1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, flange_to_palm], [0, 0, 0, 1.0]])

    def palm_position(self, q) -> np.ndarray:
        return (self._base @ forward_kinematics(q) @ self._palm)[:3, 3]

    def check(self, q_cmd, q_prev=None, dt: float | None = None) -> str:
        q = np.asarray(q_cmd, float)
        if q.shape != (6,) or not np.all(np.isfinite(q)):
            return f"joint command {q.tolist()} is not six finite numbers"
        lim = JOINT_LIMIT - self.limits.joint_margin
        bad = np.flatnonzero(np.abs(q) > lim)
        if len(bad):
            return f"joint {bad[0] + 1} command {q[bad[0]]:.3f} rad is beyond the limit +-{lim:.3f} rad"
        p = self.palm_position(q)
        x0, x1, y0, y1, z0, z1 = self.limits.workspace
        if not (x0 <= p[0] <= x1 and y0 <= p[1] <= y1 and z0 <= p[2] <= z1):
            return f"gripper position {np.round(p, 3).tolist()} m is outside the workspace box {self.limits.workspace}"
        if q_prev is not None and dt:
            speed = np.abs(q - np.asarray(q_prev, float)) / dt
            j = int(np.argmax(speed))
            if speed[j] > self.limits.max_joint_speed:
                return f"joint {j + 1} would move at {speed[j]:.2f} rad/s, above the {self.limits.max_joint_speed} rad/s limit"
        return ""


class CommandLog:
    """JSON lines of the commands a dry run would send (to a file, or stderr)."""

    def __init__(self, path: str = ""):
        self._f = open(path, "a") if path else sys.stderr  # noqa: SIM115

    def write(self, device: str, t: float, **fields) -> None:
        self._f.write(json.dumps({"device": device, "t": round(t, 4), **fields}) + "\n")
        self._f.flush()


class UR5Driver(LeafSystem):
    """ur5.position -> servoJ (checked); getActualQ -> ur5.position_measured."""

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
        servo=(0.5, 0.5, 0.1, 300.0),
    ):
        super().__init__()
        self._control, self._receive = control, receive
        self._safety, self._faults = safety, faults
        self._period, self._dry = period, dry_run
        self._log = log or CommandLog()
        self._servo = servo  # speed, acceleration, lookahead time, gain (servoJ's arguments)
        self._cmd = self.DeclareVectorInputPort("ur5.position", 6)
        self._q = self.DeclareDiscreteState(np.asarray(q_init, float))
        self._last = {"q": None, "t": None}
        self.DeclareStateOutputPort("ur5.position_measured", self._q)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._poll)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._send)

    def _fail(self, reason: str):
        self._faults.trip(reason)
        if not self._dry:
            try:
                self._control.servoStop()
            except Exception:  # the connection may be what failed
                pass
        return EventStatus.Failed(None, f"UR5: {self._faults.reason}")

    def _poll(self, context, discrete_state):
        if self._faults:
            return EventStatus.Failed(None, f"UR5: {self._faults.reason}")
        if self._dry:
            if self._last["q"] is not None:
                discrete_state.get_mutable_vector(self._q).SetFromVector(self._last["q"])
            return EventStatus.Succeeded()
        try:
            if self._receive.isProtectiveStopped():
                return self._fail("protective stop")
            q = np.asarray(self._receive.getActualQ(), float)
        except Exception as e:
            return self._fail(f"connection lost ({type(e).__name__}: {e})")
        discrete_state.get_mutable_vector(self._q).SetFromVector(q)
        return EventStatus.Succeeded()

    def _send(self, context):
        if self._faults:
            return EventStatus.Failed(None, f"UR5: {self._faults.reason}")
        q = np.asarray(self._cmd.Eval(context), float)
        t = context.get_time()
        prev = self._last["q"] if self._last["q"] is not None else context.get_discrete_state(self._q).value()
        dt = (t - self._last["t"]) if self._last["t"] is not None else None
        if self._last["q"] is not None and np.allclose(q, self._last["q"], atol=1e-6):
            return EventStatus.Succeeded()
        reason = self._safety.check(q, prev, dt if dt else self._period)
        if reason:
            return self._fail(f"refused command: {reason}")
        if self._dry:
            self._log.write("ur5", t, servoJ=[round(v, 5) for v in q])
        else:
            try:
                self._control.servoJ(q.tolist(), *self._servo[:2], self._period, *self._servo[2:])
            except Exception as e:
                return self._fail(f"connection lost ({type(e).__name__}: {e})")
        self._last.update(q=q, t=t)
        return EventStatus.Succeeded()


class RobotiqDriver(LeafSystem):
    """gripper.position (inner opening, m) -> move commands; status -> gripper.state_measured."""

    def __init__(
        self,
        client,
        faults: FaultLatch,
        force: float,
        speed: float = 0.15,
        period: float = 0.05,
        dry_run: bool = False,
        log: CommandLog | None = None,
        initial_width: float = 0.075,
    ):
        super().__init__()
        self._client, self._faults = client, faults
        self._force, self._speed, self._dry = force, speed, dry_run
        self._log = log or CommandLog()
        self._cmd = self.DeclareVectorInputPort("gripper.position", 1)
        self._state = self.DeclareDiscreteState(np.array([initial_width, 0.0]))
        self._sent = {"width": None}
        self.DeclareStateOutputPort("gripper.state_measured", self._state)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._poll)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._send)
        self._period = period

    def _poll(self, context, discrete_state):
        old = context.get_discrete_state(self._state).value()
        if self._dry:
            w = self._sent["width"] if self._sent["width"] is not None else old[0]
        else:
            try:
                w = self._client.status()["width"]
            except MogError as e:
                self._faults.trip(f"gripper: {e}")
                return EventStatus.Failed(None, f"Robotiq: {e}")
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
                self._client.move(w, self._force, self._speed)
            except MogError as e:
                self._faults.trip(f"gripper: {e}")
                return EventStatus.Failed(None, f"Robotiq: {e}")
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


class ReplayCamera(LeafSystem):
    """Plays recorded RGB-D frames (frame_*.npz with `rgb` uint8 and `depth` float32 in m), one
    per ``frame_period`` seconds, the last one held. Same ports as the simulated camera."""

    def __init__(self, folder: str, frame_period: float = 1e9):
        super().__init__()
        files = sorted(Path(folder).glob("frame_*.npz"))
        if not files:
            raise MogError(f"no recorded frames (frame_*.npz) in {folder}")
        self._frames = []
        for f in files:
            d = np.load(f)
            if "rgb" not in d or "depth" not in d:
                raise MogError(f"{f}: a frame needs arrays 'rgb' and 'depth'")
            self._frames.append((_rgba(d["rgb"]), _depth(d["depth"])))
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


def record_frame(folder: str | Path, rgb: np.ndarray, depth: np.ndarray, index: int = 0) -> Path:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"frame_{index:04d}.npz"
    np.savez_compressed(
        path,
        rgb=np.asarray(rgb)[:, :, :3],
        depth=np.asarray(depth, np.float32).reshape(np.asarray(rgb).shape[:2]),
    )
    return path


class RealSenseCamera(LeafSystem):
    """An Intel RealSense (pyrealsense2, the `hardware` extra): colour and depth aligned to colour,
    depth in metres. A new frame is grabbed at most every ``period`` seconds in a discrete update."""

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
        self._align = rs.align(rs.stream.color)
        self._images = self.DeclareAbstractState(
            AbstractValue.Make((ImageRgba8U(width, height), ImageDepth32F(width, height)))
        )
        self.DeclareAbstractOutputPort(
            "camera.rgb_image",
            lambda: AbstractValue.Make(ImageRgba8U()),
            lambda c, o: o.set_value(c.get_abstract_state(self._images).get_value()[0]),
        )
        self.DeclareAbstractOutputPort(
            "camera.depth_image",
            lambda: AbstractValue.Make(ImageDepth32F()),
            lambda c, o: o.set_value(c.get_abstract_state(self._images).get_value()[1]),
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._grab)

    def _grab(self, context, state):
        frames = self._align.process(self._pipe.wait_for_frames(timeout_ms=2000))
        rgb = np.asanyarray(frames.get_color_frame().get_data())
        depth = np.asanyarray(frames.get_depth_frame().get_data()).astype(np.float32) * self._scale
        depth[depth == 0] = np.nan
        state.get_mutable_abstract_state(self._images).set_value((_rgba(rgb), _depth(depth)))
