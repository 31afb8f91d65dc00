"""A fake UR controller behind ur_rtde's two Python interfaces, modelled on what ur_rtde does.

What each part models (ur_rtde's API reference and its source, rtde_control_interface.cpp and
rtde_receive_interface.cpp):

* Faults are reported by return value and state, not by exceptions. ``servoJ`` returns a bool:
  False when the controller is protective- or emergency-stopped, when the control script is not
  running, or when the link is gone (sendCommand catches the socket error and returns False).
* ``servoJ`` checks its own arguments first (verifyValueIsWithin): lookahead_time in
  [0.03, 0.2] s and gain in [100, 2000], else std::range_error, which pybind11 raises as
  ValueError. ``speed`` and ``acceleration`` are unused in servo mode.
* After the link drops, ``isConnected()`` turns False on both interfaces, while every getter of
  the receive interface (``getActualQ``, ``getTimestamp``, ``getSafetyMode``, ...) goes on
  returning the last cached values without error: the receive thread has stopped updating them.
* ``getActualTCPForce()``: six numbers, the force (N) and torque (N m) at the TCP in the base
  frame, as the controller estimates them less the configured payload; cached like the rest.
* ``getTimestamp()`` is the controller's time since it started (s), advancing with each RTDE
  packet (500 Hz on e-Series, 125 Hz on CB3): a frozen timestamp is the only sign of a stale
  cache while ``isConnected()`` still says True.
* ``getSafetyMode()``: 1 NORMAL, 2 REDUCED, 3 PROTECTIVE_STOP, 4 RECOVERY, 5 SAFEGUARD_STOP,
  6 SYSTEM_EMERGENCY_STOP, 7 ROBOT_EMERGENCY_STOP, 8 VIOLATION, 9 FAULT, ... ``getRobotMode()``:
  ... 3 POWER_OFF, 5 IDLE, 7 RUNNING.
* ``servoStop()``, ``stopScript()``, ``disconnect()`` exist on the control interface,
  ``disconnect()`` on the receive interface.

The fake arm follows each accepted servoJ target at once. Every call is recorded with the wall
clock (time.monotonic) at which it arrived, so a test can check what the robot received in
wall-clock time.
"""

from __future__ import annotations

import time

import numpy as np

RTDE_PERIOD = 0.002  # s between RTDE packets (e-Series, 500 Hz)


class FakeUR:
    """The controller's state, shared by the control and receive interfaces."""

    def __init__(self, q0):
        self.q = np.asarray(q0, float).copy()
        self.tcp_force = np.zeros(6)  # what the controller estimates at the TCP (N, N m)
        self.t0 = time.monotonic()
        self.connected = True  # the network link
        self.fresh = True  # the receive thread updates the cache
        self.protective_stop = False
        self.emergency_stop = False
        self.safety_mode = 1
        self.robot_mode = 7
        self.servo: list[tuple[float, list[float], float]] = []  # (wall time, q, servoJ time)
        self.calls: list[tuple] = []  # every control call, in order
        self._cache = self._read()

    # What the controller would report now; the receive cache holds the last one delivered.
    def _read(self) -> dict:
        ts = round((time.monotonic() - self.t0) / RTDE_PERIOD) * RTDE_PERIOD
        return {
            "q": list(self.q),
            "force": list(self.tcp_force),
            "ts": ts,
            "safety": self.safety_mode,
            "mode": self.robot_mode,
            "pstop": self.protective_stop,
            "estop": self.emergency_stop,
        }

    def cache(self) -> dict:
        if self.connected and self.fresh:
            self._cache = self._read()
        return self._cache

    def drop_link(self) -> None:
        self.cache()
        self.connected = False


class FakeRTDEControl:
    """rtde_control.RTDEControlInterface."""

    def __init__(self, ur: FakeUR, refuse_after: int | None = None):
        self.ur = ur
        self.refuse_after = refuse_after  # servoJ returns False from this call on (e.g. no script)
        # Test scaffolding, not ur_rtde: {n: f} calls f(controller state) once the n-th target
        # has been accepted, e.g. to drop the link or raise a protective stop mid-motion;
        # before_servo {n: f} just before the n-th servoJ call is handled (a stop that arrives
        # between the driver's poll of the robot's state and its next target).
        self.on_servo: dict = {}
        self.before_servo: dict = {}

    def isConnected(self) -> bool:
        return self.ur.connected

    def servoJ(self, q, speed, acceleration, time_, lookahead_time, gain) -> bool:
        if not 0.03 <= lookahead_time <= 0.2:
            raise ValueError(f"lookahead_time {lookahead_time} is outside [0.03, 0.2]")
        if not 100 <= gain <= 2000:
            raise ValueError(f"gain {gain} is outside [100, 2000]")
        now = time.monotonic()
        self.ur.calls.append(("servoJ", list(q)))
        ur = self.ur
        early = self.before_servo.get(sum(c[0] == "servoJ" for c in ur.calls))
        if early is not None:
            early(ur)
        if not ur.connected or ur.protective_stop or ur.emergency_stop or ur.robot_mode != 7:
            return False
        if self.refuse_after is not None and len(ur.servo) >= self.refuse_after:
            return False
        ur.servo.append((now, list(q), float(time_)))
        ur.q = np.asarray(q, float)
        hook = self.on_servo.get(len(ur.servo))
        if hook is not None:
            hook(ur)
        return True

    def servoStop(self, a: float = 10.0) -> bool:
        self.ur.calls.append(("servoStop",))
        return self.ur.connected

    def stopScript(self) -> None:
        self.ur.calls.append(("stopScript",))

    def disconnect(self) -> None:
        self.ur.calls.append(("disconnect_control",))


class FakeRTDEReceive:
    """rtde_receive.RTDEReceiveInterface: getters read the cache, never raise on a lost link."""

    def __init__(self, ur: FakeUR):
        self.ur = ur

    def isConnected(self) -> bool:
        return self.ur.connected

    def getActualQ(self) -> list[float]:
        return list(self.ur.cache()["q"])

    def getActualTCPForce(self) -> list[float]:
        return list(self.ur.cache()["force"])

    def getTimestamp(self) -> float:
        return self.ur.cache()["ts"]

    def isProtectiveStopped(self) -> bool:
        return self.ur.cache()["pstop"]

    def isEmergencyStopped(self) -> bool:
        return self.ur.cache()["estop"]

    def getSafetyMode(self) -> int:
        return self.ur.cache()["safety"]

    def getRobotMode(self) -> int:
        return self.ur.cache()["mode"]

    def disconnect(self) -> None:
        self.ur.calls.append(("disconnect_receive",))


def fake_ur5(q0, **control_kw):
    """(controller state, control interface, receive interface)."""
    ur = FakeUR(q0)
    return ur, FakeRTDEControl(ur, **control_kw), FakeRTDEReceive(ur)


def max_wall_excess(servo, v_max: float, slack: float) -> float:
    """How far (rad) the targets the robot received ran ahead of ``v_max`` in wall-clock time:
    the largest |q_j - q_i| - v_max (t_j - t_i) - slack over all pairs i < j and joints.
    Not above 0 means the stream never outran the limit by more than ``slack``."""
    if len(servo) < 2:
        return -slack
    t = np.array([s[0] for s in servo])
    q = np.array([s[1] for s in servo])
    worst = -np.inf
    for i in range(len(t) - 1):
        excess = np.abs(q[i + 1 :] - q[i]) - v_max * (t[i + 1 :, None] - t[i]) - slack
        worst = max(worst, float(excess.max()))
    return worst
