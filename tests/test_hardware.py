"""The hardware station with fake clients: no robot needed."""

import json

import numpy as np
import pytest
from fakes.robotiq_server import FakeRobotiq
from fakes.rtde import FakeRTDE
from pydrake.systems.analysis import Simulator

from mog_drake.errors import MogError
from mog_drake.hardware.drivers import (
    FaultLatch,
    RobotiqDriver,
    SafetyLimits,
    SafetyMonitor,
    UR5Driver,
    record_frame,
)
from mog_drake.hardware.robotiq import RobotiqClient
from mog_drake.station import (
    FLANGE_TO_PALM,
    PORTS_IN,
    PORTS_OUT,
    HardwareSpec,
    MakeStation,
    Scenario,
    SceneSpec,
)


def _safety(sc):
    return SafetyMonitor(SafetyLimits(), sc.robot.base, FLANGE_TO_PALM)


def _driver(sc, fake, faults=None):
    d = UR5Driver(
        fake, fake, _safety(sc), faults if faults is not None else FaultLatch(), sc.robot.home, period=0.01
    )
    ctx = d.CreateDefaultContext()
    return d, ctx


def test_ur5_driver_streams_checked_commands_and_reads_joints():
    sc = Scenario()
    fake = FakeRTDE(sc.robot.home)
    d, ctx = _driver(sc, fake)
    q = np.array(sc.robot.home) + [0.005, 0, 0, 0, 0, 0]
    d.GetInputPort("ur5.position").FixValue(ctx, q)
    Simulator(d, ctx).AdvanceTo(0.05)
    assert fake.calls[0] == ("servoJ", pytest.approx(list(q)))
    np.testing.assert_allclose(d.GetOutputPort("ur5.position_measured").Eval(ctx), q)


@pytest.mark.parametrize(
    "delta,msg",
    [
        ([0, 0, 0.9, 0, 0, 0], "outside the workspace box"),  # folds the palm down to the table
        ([0.3, 0, 0, 0, 0, 0], "rad/s, above the"),  # a jump: 30 rad/s
        ([7.0, 0, 0, 0, 0, 0], "beyond the limit"),
    ],
)
def test_ur5_driver_refuses_unsafe_commands(delta, msg):
    sc = Scenario()
    fake = FakeRTDE(sc.robot.home)
    d, ctx = _driver(sc, fake)
    d.GetInputPort("ur5.position").FixValue(ctx, np.array(sc.robot.home) + delta)
    with pytest.raises(RuntimeError, match=msg):
        Simulator(d, ctx).AdvanceTo(0.05)
    assert not [c for c in fake.calls if c[0] == "servoJ"]  # nothing unsafe was sent
    assert ("servoStop",) in fake.calls


def test_safety_monitor_accepts_the_workspace_and_refuses_below_the_table():
    from mog_drake.systems.motion import ArmMotion

    sc = Scenario()
    mon = _safety(sc)
    m = ArmMotion(sc.robot.base, FLANGE_TO_PALM, 1.0, 1.0)
    q = m.ik([0.1, 0.1, 0.042], 0.3, sc.robot.home)
    assert mon.check(q) == ""
    np.testing.assert_allclose(mon.palm_position(q), [0.1, 0.1, 0.042], atol=5e-4)
    q_low = m.ik([0.1, 0.1, 0.02], 0.3, sc.robot.home)
    assert "outside the workspace" in mon.check(q_low)


@pytest.mark.parametrize(
    "fake_kw,msg", [({"fail_after": 2}, "connection lost"), ({"protective_stop_after": 3}, "protective stop")]
)
def test_faults_halt_the_arm_and_keep_the_gripper_closed(fake_kw, msg):
    sc = Scenario()
    fake = FakeRTDE(sc.robot.home, **fake_kw)
    faults = FaultLatch()
    d, ctx = _driver(sc, fake, faults)
    d.GetInputPort("ur5.position").FixValue(ctx, np.array(sc.robot.home))
    with pytest.raises(RuntimeError, match=msg):
        Simulator(d, ctx).AdvanceTo(0.1)
    assert faults and ("servoStop",) in fake.calls
    # The gripper holds what it holds: after the fault, an open command is not sent.
    with FakeRobotiq() as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as client:
        g = RobotiqDriver(client, faults, force=40.0, period=0.05)
        gctx = g.CreateDefaultContext()
        g.GetInputPort("gripper.position").FixValue(gctx, [0.075])
        Simulator(g, gctx).AdvanceTo(0.2)
        assert not [r for r in srv.received if r.startswith("SET POS")]


def test_station_refuses_to_start_without_a_robot_address():
    sc = Scenario(hardware=HardwareSpec(enabled=True, camera="replay", replay_dir="."))
    with pytest.raises(MogError, match="explicit robot address"):
        MakeStation(sc)


@pytest.fixture(scope="module")
def replay_dir(tmp_path_factory):
    """One RGB-D frame of a 3-object table, rendered by the simulated station."""
    sc = Scenario(scene=SceneSpec(kind="cluttered", seed=5, n_objects=3))
    d, _ = MakeStation(sc)
    ctx = d.CreateDefaultContext()
    d.GetInputPort("ur5.position").FixValue(ctx, np.array(sc.robot.home))
    d.GetInputPort("gripper.position").FixValue(ctx, [0.075])
    folder = tmp_path_factory.mktemp("frames")
    record_frame(
        folder,
        d.GetOutputPort("camera.rgb_image").Eval(ctx).data,
        d.GetOutputPort("camera.depth_image").Eval(ctx).data,
    )
    return folder


def test_both_stations_export_identical_ports(replay_dir):
    sc = Scenario(
        hardware=HardwareSpec(
            enabled=True, robot_ip="192.0.2.1", camera="replay", replay_dir=str(replay_dir), dry_run=True
        )
    )
    hw, _ = MakeStation(sc)
    names = (
        {hw.get_input_port(i).get_name() for i in range(hw.num_input_ports())},
        {hw.get_output_port(i).get_name() for i in range(hw.num_output_ports())},
    )
    assert names == (set(PORTS_IN), set(PORTS_OUT))


def test_full_diagram_on_the_hardware_station_runs_an_attempt(replay_dir):
    """Perception on a recorded frame, planning, IK, and every arm and gripper command through
    the drivers to fake clients: one attempt end to end."""
    from mog_drake.systems.pick import run_pick

    sc = Scenario(
        hardware=HardwareSpec(
            enabled=True,
            robot_ip="192.0.2.1",
            camera="replay",
            replay_dir=str(replay_dir),
            max_joint_speed=3.5,
        ),
        time_limit=4.0,
    )
    fake = FakeRTDE(sc.robot.home)
    with FakeRobotiq() as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as client:
        run = run_pick(
            sc, hardware_clients={"rtde_control": fake, "rtde_receive": fake, "gripper_client": client}
        )
        received = list(srv.received)
    assert len(run.attempts) >= 1 and run.attempts[0]["picked"] is None
    servo = np.array([c[1] for c in fake.calls if c[0] == "servoJ"])
    assert len(servo) > 100
    # The palm went down to the grasp height at the planned grasp, and came back up.
    mon = _safety(sc)
    palms = np.array([mon.palm_position(q) for q in servo[::5]])
    g = np.array(run.attempts[0]["grasp"])
    low = palms[np.argmin(palms[:, 2])]
    assert low[2] == pytest.approx(0.042, abs=2e-3) and np.hypot(*(low[:2] - g[:2])) < 2e-3
    # The gripper was activated, closed (POS 255) and opened again.
    pos = [int(r.split()[2]) for r in received if r.startswith("SET POS")]
    assert received[0] == "SET ACT 1" and 255 in pos and pos[pos.index(255) + 1] < 255


def test_dry_run_logs_commands_and_sends_nothing(replay_dir, tmp_path):
    from mog_drake.systems.pick import run_pick

    log = tmp_path / "commands.jsonl"
    sc = Scenario(
        hardware=HardwareSpec(
            enabled=True,
            robot_ip="192.0.2.1",
            camera="replay",
            replay_dir=str(replay_dir),
            dry_run=True,
            command_log=str(log),
            max_joint_speed=3.5,
        ),
        time_limit=4.0,
    )
    run_pick(sc)
    lines = [json.loads(x) for x in log.read_text().splitlines()]
    assert {x["device"] for x in lines} == {"ur5", "robotiq"}
    assert any(x["device"] == "robotiq" and x["width"] == 0.0 for x in lines)


def test_gripper_cli_against_a_fake_gripper(capsys):
    from mog_drake.cli import main

    with FakeRobotiq() as srv:
        assert main(["gripper", "--ip", "127.0.0.1", "--port", str(srv.port), "close"]) == 0
        assert main(["gripper", "--ip", "127.0.0.1", "--port", str(srv.port), "status", "--json"]) == 0
        out = capsys.readouterr().out
        assert '"pos": 255' in out
    with FakeRobotiq("malformed") as srv:
        assert main(["gripper", "--ip", "127.0.0.1", "--port", str(srv.port), "status"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("mog-drake: error:") and "malformed" in err and err.count("\n") == 1
