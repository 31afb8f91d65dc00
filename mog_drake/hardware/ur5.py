"""The UR5 over ur_rtde as a LeafSystem with the simulated station's port names: the robot's
health and joints polled in periodic discrete updates; targets streamed with servoJ in
periodic publish events, each checked first (`mog_drake.hardware.safety`). A refused target,
a lost connection, a stale robot state, a stop or a safety mode other than normal latches a
fault: the arm is stopped, the gripper will not open, and the Diagram halts with a one-line
reason. ``dry_run``: nothing is sent; every command is logged and the measured joints echo
the command.
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.systems.framework import EventStatus, LeafSystem

from mog_drake.hardware.safety import CommandLog, FaultLatch, MotionBudget, SafetyMonitor, robot_health


class UR5Driver(LeafSystem):
    """ur5.position -> servoJ (checked); getActualQ -> ur5.position_measured; the force part of
    getActualTCPForce (N, base frame; the controller's estimate, less the payload's weight) ->
    ur5.wrist_force, which the guarded descent measures from its value above each grasp.

    The driver is the last line of defence and assumes nothing about what is upstream:

    * every target passes `SafetyMonitor` (joint limits, palm and fingertips in the workspace,
      every link frame above the table) and `MotionBudget` (joint speed over the time that
      really passed since the last target sent: the wall clock on hardware, simulated time in
      a dry run). A target that fails is refused, never sent, and latches a fault;
    * each poll reads the robot's health from ur_rtde's own signals, which report by value,
      not by exception: isConnected() of both interfaces, emergency and protective stop, the
      safety mode, the robot mode, and whether the receive timestamp still advances (a lost
      link leaves getActualQ returning its last cached values);
    * servoJ's return value: False is a refusal by the controller, and a fault, reported with
      the cause the controller's state gives (a stop, the safety mode, the link);
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
        *,
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
        self._f = self.DeclareDiscreteState(np.zeros(3))
        # Device bookkeeping (the last target sent, the receive timestamp) lives with the
        # device, not in the Context: it describes the robot, which no Context can rewind.
        self._last = {"q": None, "t": None, "logged": None, "stopped": False}
        self._stamp = {"ts": None, "since": None}
        self.DeclareStateOutputPort("ur5.position_measured", self._q)
        self.DeclareStateOutputPort("ur5.wrist_force", self._f)
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
            f = np.asarray(self._receive.getActualTCPForce(), float)
        except Exception as e:
            return self._fail(f"connection lost ({type(e).__name__}: {e})")
        if q.shape != (6,) or not np.all(np.isfinite(q)):
            return self._fail(f"getActualQ returned {q.tolist()}, not six finite numbers")
        if f.shape != (6,) or not np.all(np.isfinite(f)):
            return self._fail(f"getActualTCPForce returned {f.tolist()}, not six finite numbers")
        discrete_state.get_mutable_vector(self._q).SetFromVector(q)
        discrete_state.get_mutable_vector(self._f).SetFromVector(f[:3])
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
            if not ok:  # the controller's own reason, if it reports one (a stop, the link)
                cause = robot_health(self._control, self._receive)
                return self._fail(
                    f"{cause} (servoJ refused the target)"
                    if cause
                    else "servoJ returned False: the controller did not take the target "
                    "(is the control script running?)"
                )
        self._last.update(q=q, t=now)
        return EventStatus.Succeeded()
