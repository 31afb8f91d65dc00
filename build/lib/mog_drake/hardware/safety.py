"""The hardware's safety checks, shared by the drivers (`mog_drake.hardware.ur5`,
`mog_drake.hardware.robotiq`): the fault latch, the limits every arm target must satisfy
(`SafetyMonitor`: joint limits, palm and fingertips in the workspace, every link frame above
the table; `MotionBudget`: joint speed over the time that really passed), the robot's health
from ur_rtde's own signals, and a dry run's command log.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mog_drake.sim.ur5 import JOINT_LIMIT, LINK_FRAMES, ArmFrames


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
        self.frames = ArmFrames(base_xyyaw, finger_depth, finger_span)

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
