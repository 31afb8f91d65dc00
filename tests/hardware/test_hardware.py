"""The hardware station with fake clients that behave as ur_rtde and the Robotiq URCap do:
no robot needed. Tests assert on what the fake robot received (with wall-clock stamps), never
on how fast the test itself ran."""

import json
import os
import signal
import time

import numpy as np
import pytest
from fakes.robotiq_server import FakeRobotiq
from fakes.rtde import fake_ur5, max_wall_excess
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from mog_drake.errors import HardwareFault, MogError
from mog_drake.hardware.cameras import RealSenseCamera, ReplayCamera
from mog_drake.hardware.config import HardwareSpec, ReplaySource
from mog_drake.hardware.robotiq import RobotiqClient, RobotiqDriver
from mog_drake.hardware.safety import CommandLog, FaultLatch, MotionBudget, SafetyLimits, SafetyMonitor
from mog_drake.hardware.ur5 import UR5Driver
from mog_drake.scenario import Scenario
from mog_drake.station import PORTS_IN, PORTS_OUT, MakeStation, rendered_intrinsics

LIMITS = SafetyLimits()
SLACK = LIMITS.max_joint_speed * LIMITS.burst_window + 1e-3  # rad; 1 mrad for the stamps' skew


def _safety(sc, limits=None):
    return SafetyMonitor(limits or SafetyLimits(), sc.robot.base)


def _driver(sc, control, receive, faults=None, **kw):
    d = UR5Driver(
        control,
        receive,
        _safety(sc),
        faults if faults is not None else FaultLatch(),
        sc.robot.home,
        period=0.01,
        **kw,
    )
    return d, d.CreateDefaultContext()


def test_ur5_driver_streams_checked_commands_and_reads_joints():
    sc = Scenario()
    ur, control, receive = fake_ur5(sc.robot.home)
    d, ctx = _driver(sc, control, receive)
    q = np.array(sc.robot.home) + [0.005, 0, 0, 0, 0, 0]
    d.GetInputPort("ur5.position").FixValue(ctx, q)
    sim = Simulator(d, ctx)
    sim.set_target_realtime_rate(1.0)
    sim.AdvanceTo(0.1)
    assert ur.servo[0][1] == pytest.approx(list(q))
    assert len(ur.servo) >= 9  # streamed every period, changed or not
    # servoJ's time is the wall time since the last target sent (here about one period), not
    # the nominal period: summed, the times follow the fake's own receipt stamps. (Summed,
    # because one stamp taken late under load shifts two neighbouring gaps, not the sum.)
    times = np.array([s[2] for s in ur.servo[1:]])
    gaps = np.diff([s[0] for s in ur.servo])
    np.testing.assert_allclose(np.cumsum(times), np.cumsum(gaps), atol=5e-3)
    np.testing.assert_allclose(d.GetOutputPort("ur5.position_measured").Eval(ctx), q)


def test_ur5_driver_reads_the_tcp_force_and_faults_on_a_malformed_one():
    """ur5.wrist_force is getActualTCPForce's force part (its torques dropped); a reply that is
    not six finite numbers latches a fault, as a malformed getActualQ does."""
    sc = Scenario()
    ur, control, receive = fake_ur5(sc.robot.home)
    ur.tcp_force = np.array([1.5, -2.0, 41.0, 0.1, 0.2, 0.3])
    d, ctx = _driver(sc, control, receive)
    d.GetInputPort("ur5.position").FixValue(ctx, np.array(sc.robot.home))
    sim = Simulator(d, ctx)
    sim.AdvanceTo(0.03)
    np.testing.assert_allclose(d.GetOutputPort("ur5.wrist_force").Eval(ctx), [1.5, -2.0, 41.0])
    ur.tcp_force = np.array([0.0, 0.0, np.nan, 0.0, 0.0, 0.0])
    faults = FaultLatch()
    d, ctx = _driver(sc, control, receive, faults=faults)
    d.GetInputPort("ur5.position").FixValue(ctx, np.array(sc.robot.home))
    with pytest.raises(RuntimeError):
        Simulator(d, ctx).AdvanceTo(0.03)
    assert "getActualTCPForce returned" in faults.reason


@pytest.mark.parametrize(
    "delta,msg",
    [
        ([0, 0, 0.9, 0, 0, 0], "palm at .* outside the workspace box"),  # folds the palm down to the table
        ([0.3, 0, 0, 0, 0, 0], "rad/s\\), above the 1.5 rad/s limit"),  # a jump of 0.3 rad
        ([7.0, 0, 0, 0, 0, 0], "beyond the limit"),
    ],
)
def test_ur5_driver_refuses_unsafe_commands(delta, msg):
    sc = Scenario()
    ur, control, receive = fake_ur5(sc.robot.home)
    faults = FaultLatch()
    d, ctx = _driver(sc, control, receive, faults)
    d.GetInputPort("ur5.position").FixValue(ctx, np.array(sc.robot.home) + delta)
    with pytest.raises(RuntimeError, match=msg):
        Simulator(d, ctx).AdvanceTo(0.05)
    assert not ur.servo  # nothing unsafe was sent
    assert ("servoStop",) in ur.calls and faults.reason.startswith("UR5: refused command:")


# Found by search: the palm inside the workspace box, every other frame above the table, and
# the elbow 4 cm below the table top, inside the table's footprint.
Q_ELBOW_UNDER_TABLE = [-0.127, 0.309, -0.932, -0.818, 2.697, 0.131]


def test_every_link_frame_is_checked_against_the_table():
    sc = Scenario()
    mon = _safety(sc)
    f = mon.frames(Q_ELBOW_UNDER_TABLE)
    x0, x1, y0, y1, z0, z1 = mon.limits.workspace
    p = f["palm"]
    assert x0 <= p[0] <= x1 and y0 <= p[1] <= y1 and z0 <= p[2] <= z1  # a palm-only check passes it
    e = f["elbow"]
    assert e[2] == pytest.approx(-0.04, abs=3e-3) and sc.table[0] < e[0] < sc.table[1]
    assert mon.check(Q_ELBOW_UNDER_TABLE).startswith("elbow at")
    # A fingertip below the table top is refused too, the palm above its box floor.
    assert mon.check(sc.robot.home) == ""


def test_safety_monitor_accepts_the_workspace_and_refuses_below_the_table():
    from mog_drake.systems.motion import ArmMotion

    sc = Scenario()
    mon = _safety(sc)
    m = ArmMotion(sc.robot.base, 1.0, 1.0)
    q = m.ik([0.1, 0.1, 0.042], 0.3, sc.robot.home)
    assert mon.check(q) == ""
    np.testing.assert_allclose(mon.palm_position(q), [0.1, 0.1, 0.042], atol=5e-4)
    f = mon.frames(q)
    assert f["left fingertip"][2] == pytest.approx(0.002, abs=5e-4)  # the grasp height: 2 mm clear
    q_low = m.ik([0.1, 0.1, 0.02], 0.3, sc.robot.home)
    assert "outside the workspace" in mon.check(q_low)


def test_motion_budget_bounds_motion_over_any_interval():
    b = MotionBudget(v_max=1.0, window=0.03)
    b.start(np.zeros(6), 0.0)
    q = np.zeros(6)
    # Steady motion at 0.9 rad/s, 10 ms apart, with jitter: admitted.
    t = 0.0
    for k in range(100):
        t += 0.01 + (0.004 if k % 2 else -0.004)
        q[0] += 0.009
        assert b.admit(q, t) == ""
    # A burst: the same steps 0.1 ms apart. The saved slack (30 mrad) runs out within 4 steps.
    refused = None
    for k in range(10):
        t += 1e-4
        q[0] += 0.009
        if b.admit(q, t):
            refused = k
            break
    assert refused is not None and refused <= 4
    # After a pause, a jump larger than the slack is refused, however long the pause.
    b2 = MotionBudget(v_max=1.0, window=0.03)
    b2.start(np.zeros(6), 0.0)
    assert "above the 1.0 rad/s limit" in b2.admit([1.0, 0, 0, 0, 0, 0], 2.0)
    assert b2.admit([0.02, 0, 0, 0, 0, 0], 2.0) == ""


class _Sleeper(LeafSystem):
    """Stands for perception or planning inside the Diagram's loop: sleeps in an unrestricted
    update at ``at`` (simulated s)."""

    def __init__(self, at: float, seconds: float):
        super().__init__()
        self._done = [False]
        self.DeclarePeriodicUnrestrictedUpdateEvent(0.01, 0.0, self._update)
        self._at, self._seconds = at, seconds

    def _update(self, context, state):
        if context.get_time() >= self._at and not self._done[0]:
            self._done[0] = True
            time.sleep(self._seconds)


def _ramp(q0, dq, t0, t1):
    """q0 until t0, then a straight line to q0 + dq at t1 (held after)."""
    q0 = np.asarray(q0, float)
    times, knots = [t0, t1], [q0, q0 + dq]
    if t0 > 0:
        times, knots = [0.0, *times], [q0, *knots]
    return PiecewisePolynomial.FirstOrderHold(times, np.column_stack(knots))


def test_finding_1_a_burst_after_a_slow_step_is_refused():
    """Joint 1 moves 0.5 rad over 1 s; a system sleeps 2 s at t = 0.5 s under a real-time
    Simulator, which then races to catch up. The driver refuses the burst: nothing the robot
    received outruns the limit in wall-clock time."""
    sc = Scenario()
    ur, control, receive = fake_ur5(sc.robot.home)
    faults = FaultLatch()
    b = DiagramBuilder()
    traj = b.AddSystem(TrajectorySource(_ramp(sc.robot.home, [0.5, 0, 0, 0, 0, 0], 0.0, 1.0)))
    drv = b.AddSystem(UR5Driver(control, receive, _safety(sc), faults, sc.robot.home, period=0.01))
    b.AddSystem(_Sleeper(0.5, 2.0))
    b.Connect(traj.get_output_port(), drv.GetInputPort("ur5.position"))
    sim = Simulator(b.Build())
    sim.set_target_realtime_rate(1.0)
    with pytest.raises(RuntimeError, match="refused command: joint 1 would move"):
        sim.AdvanceTo(1.5)
    assert faults and ("servoStop",) in ur.calls
    sent = np.array([s[1][0] for s in ur.servo])
    # The motion was cut short: the last fifth of the ramp (0.5 rad) never reached the robot. How
    # far it got depends on how fast this machine races (0.355 rad on a starved one); the
    # wall-clock bound below is what keeps it safe.
    assert sent.max() - sc.robot.home[0] < 0.5 - 0.1
    assert max_wall_excess(ur.servo, LIMITS.max_joint_speed, SLACK) <= 0


def test_finding_2_a_jump_after_a_pause_is_refused(tmp_path):
    """A constant command for 2 s, then a 1 rad jump: refused (a dry run measures the same way
    in simulated time), and never logged as sent."""
    sc = Scenario()
    log = tmp_path / "commands.jsonl"
    faults = FaultLatch()
    d = UR5Driver(
        None, None, _safety(sc), faults, sc.robot.home, period=0.01, dry_run=True, log=CommandLog(str(log))
    )
    b = DiagramBuilder()
    drv = b.AddSystem(d)
    traj = b.AddSystem(TrajectorySource(_ramp(sc.robot.home, [1.0, 0, 0, 0, 0, 0], 2.0, 2.0001)))
    b.Connect(traj.get_output_port(), drv.GetInputPort("ur5.position"))
    with pytest.raises(RuntimeError, match="joint 1 would move"):
        Simulator(b.Build()).AdvanceTo(3.0)
    sent = [json.loads(x)["servoJ"][0] for x in log.read_text().splitlines()]
    assert max(sent) - sc.robot.home[0] <= LIMITS.max_joint_speed * LIMITS.burst_window + 1e-5


def _run_driver_until_fault(sc, ur, control, receive, seconds=1.0, **kw):
    faults = FaultLatch()
    d, ctx = _driver(sc, control, receive, faults, **kw)
    d.GetInputPort("ur5.position").FixValue(ctx, np.array(sc.robot.home))
    sim = Simulator(d, ctx)
    sim.set_target_realtime_rate(1.0)
    with pytest.raises(RuntimeError) as e:
        sim.AdvanceTo(seconds)
    return faults, str(e.value)


def test_finding_3_a_lost_connection_is_noticed():
    """ur_rtde raises nothing when the link drops: isConnected() turns False, servoJ returns
    False and getActualQ returns the cached values. The driver stops at the next poll."""
    sc = Scenario()
    ur, control, receive = fake_ur5(sc.robot.home)
    control.on_servo = {10: lambda ur: ur.drop_link()}
    faults, msg = _run_driver_until_fault(sc, ur, control, receive)
    assert faults.reason.startswith("UR5: connection lost") or "servoJ returned False" in faults.reason
    calls_after_drop = [c for c in ur.calls[10:] if c[0] == "servoJ"]
    assert len(calls_after_drop) <= 1  # at most the one servoJ that reported False
    assert ("servoStop",) in ur.calls


@pytest.mark.parametrize(
    "what,expected",
    [
        (lambda ur: setattr(ur, "protective_stop", True), "UR5: protective stop"),
        (lambda ur: setattr(ur, "emergency_stop", True), "UR5: emergency stop"),
        (lambda ur: setattr(ur, "safety_mode", 5), "UR5: safety mode 5 (safeguard stop)"),
        (lambda ur: setattr(ur, "robot_mode", 5), "UR5: robot mode 5 (idle), not running"),
        (lambda ur: setattr(ur, "fresh", False), "UR5: robot state is stale"),
    ],
    ids=["protective", "emergency", "safeguard", "idle", "stale"],
)
def test_every_health_signal_latches_a_fault_and_stops_the_arm(what, expected):
    sc = Scenario()
    ur, control, receive = fake_ur5(sc.robot.home)
    control.on_servo = {5: what}
    faults, msg = _run_driver_until_fault(sc, ur, control, receive)
    assert faults.reason.startswith(expected), faults.reason
    assert expected in msg
    assert ("servoStop",) in ur.calls


def test_a_servoj_refused_by_the_controller_is_a_fault():
    sc = Scenario()
    ur, control, receive = fake_ur5(sc.robot.home, refuse_after=3)
    faults, _ = _run_driver_until_fault(sc, ur, control, receive)
    assert faults.reason.startswith("UR5: servoJ returned False: the controller did not take the target")
    assert len([c for c in ur.calls if c[0] == "servoJ"]) == 4


@pytest.mark.parametrize(
    "what,expected",
    [
        (lambda ur: setattr(ur, "protective_stop", True), "UR5: protective stop (servoJ refused the target)"),
        (lambda ur: ur.drop_link(), "UR5: connection lost: the RTDE receive interface is disconnected"),
    ],
    ids=["protective", "link"],
)
def test_a_servoj_refused_for_a_stop_or_a_lost_link_names_the_cause(what, expected):
    """The stop or the loss arrives between the driver's poll and its next target: servoJ
    returns False, and the fault names what the controller reports, not the return value."""
    sc = Scenario()
    ur, control, receive = fake_ur5(sc.robot.home)
    control.before_servo = {5: what}
    faults, _ = _run_driver_until_fault(sc, ur, control, receive)
    assert faults.reason.startswith(expected), faults.reason


def test_faults_keep_the_gripper_closed():
    sc = Scenario()
    ur, control, receive = fake_ur5(sc.robot.home)
    control.on_servo = {2: lambda ur: setattr(ur, "protective_stop", True)}
    faults, _ = _run_driver_until_fault(sc, ur, control, receive)
    assert faults
    # The gripper holds what it holds: after the fault, an open command is not sent.
    with FakeRobotiq(active=True) as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as client:
        g = RobotiqDriver(client, faults, force=40.0, period=0.05)
        gctx = g.CreateDefaultContext()
        g.GetInputPort("gripper.position").FixValue(gctx, [0.075])
        Simulator(g, gctx).AdvanceTo(0.2)
        assert not [r for r in srv.received if r.startswith("SET")]


def test_an_object_lost_after_the_lift_is_warned_and_counted_as_a_drop():
    """The fake closes onto an object (OBJ 2), then the object slips out: the fingers finish
    the close (OBJ 3) with no new command. The driver warns, notes when, and the attempt
    under way counts it as dropped; opening over the bin afterwards is no loss."""
    from mog_drake.systems.pick_run import PickRun, attempt_line

    faults = FaultLatch()
    with (
        FakeRobotiq(active=True, object_at=150) as srv,
        RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as client,
    ):
        g = RobotiqDriver(client, faults, force=40.0, period=0.05)
        gctx = g.CreateDefaultContext()
        sim = Simulator(g, gctx)
        sim.set_target_realtime_rate(1.0)  # the fake's moves take wall-clock time
        g.GetInputPort("gripper.position").FixValue(gctx, [0.0])
        sim.AdvanceTo(0.5)
        assert g.lost == [] and g.get_output_port().Eval(gctx)[0] > 0.01  # held, jaws apart
        srv.lose()
        with pytest.warns(UserWarning, match=r"gripper: lost what it held at t=0\.[5-9]\d s \(OBJ 2 -> 3"):
            sim.AdvanceTo(0.8)
        assert len(g.lost) == 1 and 0.5 <= g.lost[0] <= 0.8
        g.GetInputPort("gripper.position").FixValue(gctx, [0.085])  # open over the bin
        sim.AdvanceTo(1.2)
        assert len(g.lost) == 1 and not faults
    a = {"group": [0, 1], "shapes": ["a", "b"], "planning_time": 0.1, "physics_checks": 1}
    run = PickRun(
        objects=2,
        attempts=[
            {**a, "start": 0.0, "end": 2.0, "picked": None, "lost": 1},
            {**a, "start": 2.0, "end": 4.0, "picked": None, "lost": 0},
        ],
    )
    assert run.summary()["dropped"] == 1
    assert "dropped in transit" in attempt_line(1, run.attempts[0])
    assert "dropped" not in attempt_line(2, run.attempts[1])


@pytest.mark.parametrize(
    "mode,expected",
    [
        ("fault", "gripper: fault 0x0E (overcurrent)"),
        ("ignore", "gripper: the gripper did not take the command"),
    ],
)
def test_gripper_driver_latches_gripper_faults(mode, expected):
    faults = FaultLatch()
    with FakeRobotiq(mode, active=True) as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as client:
        g = RobotiqDriver(client, faults, force=40.0, period=0.05, move_timeout=0.3)
        gctx = g.CreateDefaultContext()
        g.GetInputPort("gripper.position").FixValue(gctx, [0.0])
        sim = Simulator(g, gctx)
        sim.set_target_realtime_rate(1.0)  # the move timeout is wall-clock time
        with pytest.raises(RuntimeError, match="gripper: "):
            sim.AdvanceTo(1.0)
    assert faults.reason.startswith(expected), faults.reason


def test_a_gripper_that_never_ends_a_move_faults_however_often_it_is_commanded():
    """The URCap's fake in "stuck" mode takes every command (PRE) but never ends a move (OBJ
    stays 0). Commands every 0.1 s, each to a new width, must not restart the deadline: the
    fault comes once the first move has run past move_timeout (0.3 s), not never."""
    faults = FaultLatch()
    with (
        FakeRobotiq("stuck", active=True) as srv,
        RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as client,
    ):
        g = RobotiqDriver(client, faults, force=40.0, period=0.05, move_timeout=0.3)
        gctx = g.CreateDefaultContext()
        sim = Simulator(g, gctx)
        sim.set_target_realtime_rate(1.0)  # the move timeout is wall-clock time
        sent = []
        with pytest.raises(RuntimeError, match="gripper: "):
            for k in range(40):
                g.GetInputPort("gripper.position").FixValue(gctx, [0.07 - 0.001 * k])
                sent.append(k)
                sim.AdvanceTo(0.1 * (k + 1))
    assert faults.reason.startswith("gripper: still moving 0.3 s after the command"), faults.reason
    # One deadline, not one per command: the fault came with the first move's, within a
    # few commands (a pacing simulator only ever lags the wall clock, so never more).
    assert len(sent) <= 8, len(sent)


def test_station_refuses_to_start_without_a_robot_address():
    sc = Scenario(hardware=HardwareSpec(enabled=True, camera=ReplaySource(dir="."), max_joint_speed=3.5))
    with pytest.raises(MogError, match="explicit robot address"):
        MakeStation(sc)


def test_replayed_frames_bring_their_own_intrinsics(replay_dir, tmp_path):
    """The replay camera reads back the intrinsics its frames were recorded with, and the
    hardware station hands them to perception; frames recorded before intrinsics were stored
    fall back on the scenario's camera with a warning; mixed or invalid ones are refused."""
    sc = Scenario(hardware=_hw(replay_dir, dry_run=True))
    _, handles = MakeStation(sc)
    assert handles.camera_intrinsics == pytest.approx(rendered_intrinsics(sc.camera))
    frame = dict(np.load(next(replay_dir.glob("frame_*.npz"))))
    old = tmp_path / "old"
    old.mkdir()
    np.savez(old / "frame_0000.npz", rgb=frame["rgb"], depth=frame["depth"])
    with pytest.warns(UserWarning, match="without intrinsics; using the scenario camera's"):
        cam = ReplayCamera(str(old), fallback_intrinsics=(600.0, 600.0, 320.0, 240.0))
    assert cam.intrinsics == (600.0, 600.0, 320.0, 240.0)
    with pytest.raises(MogError, match="frames without intrinsics"):
        ReplayCamera(str(old))
    np.savez(
        old / "frame_0001.npz",
        rgb=frame["rgb"],
        depth=frame["depth"],
        intrinsics=[600.0, 600.0, 320.0, 240.0],
    )
    with pytest.raises(MogError, match="different intrinsics"):
        ReplayCamera(str(old), fallback_intrinsics=(600.0, 600.0, 320.0, 240.0))
    bad = tmp_path / "bad"
    bad.mkdir()
    np.savez(
        bad / "frame_0000.npz", rgb=frame["rgb"], depth=frame["depth"], intrinsics=[0.0, 600.0, 320.0, 240.0]
    )
    with pytest.raises(MogError, match=r"intrinsics must be \(fx, fy, cx, cy\) with fx, fy > 0"):
        ReplayCamera(str(bad))


def test_realsense_camera_reads_intrinsics_and_depth_scale_from_the_device(monkeypatch):
    """The RealSense source takes fx, fy, cx, cy from the colour stream's profile (not from
    the scenario's field of view) and scales z16 depth by the device's depth scale; a lens
    with distortion is flagged, a stream of another size is refused (fake: fakes/realsense.py)."""
    import sys

    from fakes import realsense

    rgb = np.full((48, 64, 3), 120, np.uint8)
    depth = np.full((48, 64), 0.8)
    depth[:4] = np.nan  # no depth: z16 0
    monkeypatch.setitem(sys.modules, "pyrealsense2", realsense.module(rgb, depth, depth_scale=0.00025))
    cam = RealSenseCamera(64, 48, 30)
    assert cam.intrinsics == (615.0, 615.5, 318.2, 241.7)
    sim = Simulator(cam)
    sim.AdvanceTo(0.05)  # the first grab (at t = 0)
    ctx = sim.get_context()
    got = cam.GetOutputPort("camera.depth_image").Eval(ctx).data[:, :, 0]
    assert np.isnan(got[:4]).all() and got[4:] == pytest.approx(0.8, abs=0.00025)
    assert (cam.GetOutputPort("camera.rgb_image").Eval(ctx).data[:, :, :3] == 120).all()

    monkeypatch.setitem(sys.modules, "pyrealsense2", realsense.module(rgb, depth, frames=False))
    with pytest.raises(
        HardwareFault, match=r"^camera: no frame within 2 s \(Frame didn't arrive within 2000\)$"
    ):
        Simulator(RealSenseCamera(64, 48, 30)).AdvanceTo(0.05)
    monkeypatch.setitem(sys.modules, "pyrealsense2", realsense.module(rgb, depth, coeffs=(0.1, 0, 0, 0, 0)))
    with pytest.warns(UserWarning, match="lens distortion"):
        RealSenseCamera(64, 48, 30)
    monkeypatch.setitem(sys.modules, "pyrealsense2", realsense.module(rgb, depth, stream_size=(640, 480)))
    with pytest.raises(MogError, match="colour stream is 640 x 480, asked for 64 x 48"):
        RealSenseCamera(64, 48, 30)


def _hw(replay_dir, **kw):
    """A hardware station on recorded frames; its driver allows the default planned speed."""
    kw.setdefault("max_joint_speed", 3.5)
    return HardwareSpec(enabled=True, robot_ip="192.0.2.1", camera=ReplaySource(dir=str(replay_dir)), **kw)


def test_station_refuses_a_robot_that_is_not_ready_and_closes_what_it_opened(replay_dir):
    sc = Scenario(hardware=_hw(replay_dir))
    ur, control, receive = fake_ur5(sc.robot.home)
    ur.protective_stop = True
    with FakeRobotiq() as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as client:
        with pytest.raises(HardwareFault, match="^UR5: not ready: protective stop$"):
            MakeStation(
                sc,
                hardware_clients={"rtde_control": control, "rtde_receive": receive, "gripper_client": client},
            )
        assert not srv.received  # the gripper was not activated
    assert ("disconnect_control",) in ur.calls and ("disconnect_receive",) in ur.calls


def test_both_stations_export_identical_ports(replay_dir):
    sc = Scenario(hardware=_hw(replay_dir, dry_run=True))
    hw, _ = MakeStation(sc)
    names = (
        {hw.get_input_port(i).get_name() for i in range(hw.num_input_ports())},
        {hw.get_output_port(i).get_name() for i in range(hw.num_output_ports())},
    )
    assert names == (set(PORTS_IN), set(PORTS_OUT))


def test_full_pick_real_time_with_a_planner_slowed_by_2_s(replay_dir, monkeypatch):
    """Perception on a recorded frame, planning slowed by 2 s, IK, and every arm and gripper
    command through the drivers to fakes that behave as ur_rtde and the URCap: one attempt end
    to end in real time. Nothing the robot received outran the joint-speed limit in wall-clock
    time, and the run ended with the arm stopped and every connection closed."""
    import mog_drake.systems.planner as ls
    from mog_drake.systems.pick import run_pick

    real_next_pick = ls.next_pick
    slowed = []

    def slow_next_pick(*a, **kw):
        time.sleep(2.0)
        slowed.append(time.monotonic())
        return real_next_pick(*a, **kw)

    monkeypatch.setattr(ls, "next_pick", slow_next_pick)
    # The first decision comes after 2 s of sleep plus perception and planning in real time:
    # 6 s leave room for a loaded machine (4 s did not, beside two simulations).
    sc = Scenario(hardware=_hw(replay_dir), time_limit=6.0)
    ur, control, receive = fake_ur5(sc.robot.home)
    with FakeRobotiq() as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as client:
        run = run_pick(
            sc, hardware_clients={"rtde_control": control, "rtde_receive": receive, "gripper_client": client}
        )
        received = list(srv.received)
    assert slowed and len(run.attempts) >= 1 and run.attempts[0]["picked"] is None
    servo = np.array([s[1] for s in ur.servo])
    assert len(servo) > 100
    # Planning ran beside the servo loop: the robot received targets all through each 2-s
    # stall, not a silence and then a burst (one per servo period: 200 in 2 s).
    during = [s for s in ur.servo if slowed[0] - 2.0 < s[0] < slowed[0]]
    assert len(during) > 0.8 * 2.0 / sc.hardware.servo_period
    # The stream never outran the limit in wall-clock time, the 2-s stalls included.
    assert max_wall_excess(ur.servo, 3.5, 3.5 * LIMITS.burst_window + 1e-3) <= 0
    # Motion after the first stall started at wall pace: the arm moved after planning ended.
    moved = [s[0] for s in ur.servo if not np.allclose(s[1], sc.robot.home, atol=1e-4)]
    assert moved and moved[0] > slowed[0]
    # The palm went down to the grasp height at the planned grasp, and came back up.
    mon = _safety(sc)
    palms = np.array([mon.palm_position(q) for q in servo[::5]])
    g = np.array(run.attempts[0]["grasp"])
    low = palms[np.argmin(palms[:, 2])]
    assert low[2] == pytest.approx(0.042, abs=2e-3) and np.hypot(*(low[:2] - g[:2])) < 2e-3
    # The gripper was activated (STA polled to 3), closed (POS 255) and opened again, each
    # move one atomic request with its force and speed.
    assert received[:2] == ["GET STA", "SET ACT 1"] and "GET FLT" in received
    moves = [r for r in received if r.startswith("SET SPE")]
    pos = [int(r.split()[6]) for r in moves]
    assert 255 in pos and pos[pos.index(255) + 1] < 255
    # The end of the run stopped the arm and closed the connections.
    assert ("servoStop",) in ur.calls and ("stopScript",) in ur.calls
    assert ("disconnect_control",) in ur.calls and ("disconnect_receive",) in ur.calls


def test_ctrl_c_stops_the_arm_and_closes_the_connections(replay_dir):
    from mog_drake.systems.pick import run_pick

    sc = Scenario(hardware=_hw(replay_dir), time_limit=4.0)
    ur, control, receive = fake_ur5(sc.robot.home)
    polls = [0]
    real = receive.getActualQ

    def interrupted():
        polls[0] += 1
        if polls[0] == 30:
            raise KeyboardInterrupt  # SIGINT arriving while the driver reads the joints
        return real()

    receive.getActualQ = interrupted
    with FakeRobotiq() as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as client:
        with pytest.raises(KeyboardInterrupt):
            run_pick(
                sc,
                hardware_clients={"rtde_control": control, "rtde_receive": receive, "gripper_client": client},
            )
    assert ("servoStop",) in ur.calls and ("disconnect_control",) in ur.calls


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_stop_the_arm_and_exit_128_plus_the_signal(
    replay_dir, tmp_path, monkeypatch, signum, capsys
):
    """`kill` (SIGTERM) or a closed terminal (SIGHUP) mid-motion, through the CLI's own
    connection path: no servoJ target after the signal, then servoStop, stopScript and both
    disconnects (what ur_rtde needs to end the servo stream), and one line with exit 143 / 129."""
    from mog_drake.cli import main

    sc = Scenario()
    ur, control, receive = fake_ur5(sc.robot.home)
    _fake_rtde_modules(monkeypatch, ur, control, receive)
    sent = []

    def kill(ur):
        sent.append(len(ur.servo))
        os.kill(os.getpid(), signum)

    control.on_servo[40] = kill
    before = signal.getsignal(signum)
    with FakeRobotiq() as srv:
        scenario = tmp_path / "hw.yaml"
        scenario.write_text(
            f"hardware: {{enabled: true, camera: !ReplaySource {{dir: '{replay_dir}'}}, "
            f"gripper_port: {srv.port}, max_joint_speed: 3.5}}\ntime_limit: 10.0\n"
        )
        code = main(["pick", "--scenario", str(scenario), "--robot-ip", "127.0.0.1"])
    err = capsys.readouterr().err
    assert code == 128 + signum and err == f"mog-drake: terminated by {signal.Signals(signum).name}\n"
    assert sent == [40] and len(ur.servo) == 40  # not one target more
    calls = [c[0] for c in ur.calls if c[0] != "servoJ"]
    assert calls[-4:] == ["servoStop", "stopScript", "disconnect_control", "disconnect_receive"], calls
    # The process is stopping: a second signal must not kill it before it exits 128 + signum.
    assert signal.getsignal(signum) == signal.SIG_IGN
    signal.signal(signum, before)


def test_dry_run_logs_commands_and_sends_nothing(replay_dir, tmp_path):
    from mog_drake.systems.pick import run_pick

    log = tmp_path / "commands.jsonl"
    sc = Scenario(
        hardware=_hw(
            replay_dir,
            dry_run=True,
            command_log=str(log),
        ),
        time_limit=4.0,
    )
    run_pick(sc)
    lines = [json.loads(x) for x in log.read_text().splitlines()]
    assert {x["device"] for x in lines} == {"ur5", "robotiq"}
    assert any(x["device"] == "robotiq" and x["width"] == 0.0 for x in lines)


def _fake_rtde_modules(monkeypatch, ur, control, receive):
    """ur_rtde's two modules, answering with the fakes: the CLI's own connection path runs."""
    import sys
    import types

    rc = types.ModuleType("rtde_control")
    rc.RTDEControlInterface = lambda ip: control
    rr = types.ModuleType("rtde_receive")
    rr.RTDEReceiveInterface = lambda ip: receive
    monkeypatch.setitem(sys.modules, "rtde_control", rc)
    monkeypatch.setitem(sys.modules, "rtde_receive", rr)


def test_a_refused_arm_command_ends_pick_with_one_line_and_exit_3(replay_dir, tmp_path, monkeypatch, capsys):
    from mog_drake.cli import main

    sc = Scenario()
    ur, control, receive = fake_ur5(sc.robot.home)
    _fake_rtde_modules(monkeypatch, ur, control, receive)
    # The palm may not go more than 2 cm below where it starts: the descent to the first grasp
    # is refused by the driver's safety monitor.
    floor = _safety(sc).palm_position(sc.robot.home)[2] - 0.02
    with FakeRobotiq() as srv:
        scenario = tmp_path / "hw.yaml"
        scenario.write_text(
            f"hardware: {{enabled: true, camera: !ReplaySource {{dir: '{replay_dir}'}}, "
            f"gripper_port: {srv.port}, max_joint_speed: 3.5, "
            f"workspace: [-0.45, 0.45, -0.45, 0.55, {floor:.4f}, 0.9]}}\ntime_limit: 8.0\n"
        )
        code = main(["pick", "--scenario", str(scenario), "--robot-ip", "127.0.0.1"])
    err = capsys.readouterr().err
    assert code == 3
    assert err.startswith("mog-drake: error: UR5: refused command: palm") and err.count("\n") == 1, err
    assert "outside the workspace box" in err
    assert ("servoStop",) in ur.calls and ("disconnect_control",) in ur.calls


def test_a_hardware_scenario_planned_faster_than_its_driver_allows_is_refused_at_load(
    tmp_path, monkeypatch, capsys
):
    """Planned at 3.14 rad/s, the driver allowing 0.2: one line naming both keys, exit 2,
    and nothing connected."""
    from mog_drake.cli import main

    sc = Scenario()
    ur, control, receive = fake_ur5(sc.robot.home)
    _fake_rtde_modules(monkeypatch, ur, control, receive)
    scenario = tmp_path / "hw.yaml"
    scenario.write_text("hardware: {enabled: true, max_joint_speed: 0.2}\n")
    code = main(["pick", "--scenario", str(scenario), "--robot-ip", "127.0.0.1"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "robot.max_joint_speed 3.14" in err and "hardware.max_joint_speed 0.2" in err
    assert ur.calls == []


def test_gripper_cli_against_a_fake_gripper(capsys):
    from mog_drake.cli import main

    with FakeRobotiq() as srv:
        assert main(["gripper", "--ip", "127.0.0.1", "--port", str(srv.port), "close"]) == 0
        out = capsys.readouterr().out
        assert "close: at the requested position, no object" in out and "width 0.0 mm" in out
        assert main(["gripper", "--ip", "127.0.0.1", "--port", str(srv.port), "status", "--json"]) == 0
        assert json.loads(capsys.readouterr().out)["pos"] == 255
    with FakeRobotiq(object_at=200) as srv:
        assert main(["gripper", "--ip", "127.0.0.1", "--port", str(srv.port), "close"]) == 0
        assert "close: stopped on an object while closing" in capsys.readouterr().out


@pytest.mark.parametrize(
    "mode,kw,expected",
    [
        ("fault", {}, "gripper: fault 0x0E (overcurrent)"),
        ("ignore", {}, "gripper: the gripper did not take the command: PRE 0, expected 255"),
        ("stuck", {}, "gripper: still moving"),
        ("never_active", {}, "gripper: activation did not complete"),
        ("garbage", {}, "gripper: garbage in reply"),
        ("malformed", {}, "gripper: malformed reply 'POS banana'"),
    ],
)
def test_gripper_cli_close_fails_with_one_line_naming_the_fault(mode, kw, expected, capsys):
    from mog_drake.cli import main

    with FakeRobotiq(mode, **kw) as srv:
        code = main(
            [
                "gripper",
                "--ip",
                "127.0.0.1",
                "--port",
                str(srv.port),
                "--timeout",
                "0.3",
                "--move-timeout",
                "0.5",
                "close",
            ]
        )
    err = capsys.readouterr().err
    assert code == 3
    assert err.startswith(f"mog-drake: error: {expected}") and err.count("\n") == 1, err


def test_gripper_cli_refuses_a_bad_force_before_sending_anything(capsys):
    from mog_drake.cli import main

    with FakeRobotiq() as srv:
        assert main(["gripper", "--ip", "127.0.0.1", "--port", str(srv.port), "--force", "500", "close"]) == 2
        time.sleep(0.1)
        assert srv.received == []
    assert "--force" in capsys.readouterr().err


def test_a_push_on_hardware_streams_within_the_limits_with_the_jaws_closed(replay_dir, monkeypatch):
    """push-mog's push through the drivers to fakes that behave as ur_rtde and the URCap, in
    real time: the jaws were closed (POS 255) before the palm came down, the palm went along
    the push's line at grasp height, and no target outran the joint-speed limit in wall-clock
    time."""
    import mog_drake.systems.planner as ls
    from mog_drake.geometry.push import Push
    from mog_drake.planning.picking import PickDecision
    from mog_drake.systems.pick import run_pick

    push = Push((0.0, -0.05), (0.0, 0.0), np.pi / 2, 0, 1, 0.04)

    def push_now(scene, *a, **kw):
        return PickDecision("push", group=(0, 1), expected=(0, 1), push=push, now=1)

    monkeypatch.setattr(ls, "next_pick", push_now)
    sc = Scenario(hardware=_hw(replay_dir), time_limit=4.0)
    sc.planner.mode = "push-mog"
    ur, control, receive = fake_ur5(sc.robot.home)
    with FakeRobotiq() as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as client:
        run = run_pick(
            sc, hardware_clients={"rtde_control": control, "rtde_receive": receive, "gripper_client": client}
        )
        received, received_at = list(srv.received), list(srv.received_at)
    assert run.pushes and run.pushes[0]["push"]["target"] == 0
    assert max_wall_excess(ur.servo, 3.5, 3.5 * LIMITS.burst_window + 1e-3) <= 0
    mon = _safety(sc)
    assert all(mon.check(s[1]) == "" for s in ur.servo)
    stamps = np.array([s[0] for s in ur.servo])
    palms = np.array([mon.palm_position(s[1]) for s in ur.servo])
    low = palms[:, 2] < 0.045  # at grasp height (0.042 m)
    assert low.any()
    along = palms[low]
    assert np.abs(along[:, 0]).max() < 2e-3  # on the line x = 0 ...
    assert along[:, 1].min() < -0.045 and along[:, 1].max() > -0.005  # ... from its start to its end
    # The close (POS 255) went out before the palm first came down.
    closes = [k for k, r in enumerate(received) if r.startswith("SET SPE") and int(r.split()[6]) == 255]
    assert closes and received_at[closes[0]] < stamps[np.argmax(low)]
