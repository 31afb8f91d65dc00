"""ControllerSystem: its state machine on fixed inputs, a changed table, unreachable grasps, the
drop pose above the bin."""

import numpy as np
import pytest

from mog_drake.geometry.gripper import OPEN_WIDTH
from mog_drake.scenario import Scenario


def _controller_with_fixed_inputs(with_check=False):
    """A ControllerSystem alone: the arm at home, the jaws at 30 mm, a decision to set, every
    scene perceived. Returns (controller, context, decision input value, simulator), and the
    change check's input value if ``with_check`` (else every check says unchanged)."""
    from pydrake.common.value import AbstractValue
    from pydrake.systems.analysis import Simulator

    from mog_drake.systems.controller import ControllerSystem
    from mog_drake.systems.messages import Checked, Decision, Perceived
    from mog_drake.systems.motion import ArmMotion

    sc = Scenario()
    m = ArmMotion(sc.robot.base, sc.robot.max_joint_speed, sc.robot.max_joint_acceleration)
    c = ControllerSystem(m, sc.robot.home, sc.bin.center, sc.bin.depth)
    ctx = c.CreateDefaultContext()
    c.GetInputPort("ur5.position_measured").FixValue(ctx, np.array(sc.robot.home))
    c.GetInputPort("gripper.state_measured").FixValue(ctx, [0.03, 0.0])
    c.GetInputPort("ur5.wrist_force").FixValue(ctx, np.zeros(3))
    decision = c.GetInputPort("decision").FixValue(ctx, AbstractValue.Make(Decision()))
    c.GetInputPort("scene").FixValue(ctx, AbstractValue.Make(Perceived(counter=10**6)))
    checked = c.GetInputPort("checked").FixValue(ctx, AbstractValue.Make(Checked(counter=-1)))
    if not with_check:
        c.GetInputPort("checked").FixValue(ctx, AbstractValue.Make(Checked(counter=2)))  # unchanged
    return (c, ctx, decision, Simulator(c, ctx)) + ((checked,) if with_check else ())


def test_controller_state_machine_with_fixed_inputs():
    """Fed a fixed decision, the controller asks, moves, closes, lifts, goes to the bin, opens
    and returns, then asks again."""
    from mog_drake.planning.decision import PickDecision
    from mog_drake.systems.planner import Decision

    c, ctx, decision, sim = _controller_with_fixed_inputs()
    modes, grippers = [], []
    sim.AdvanceTo(0.5)
    assert c.state(ctx).mode == "wait" and c.GetOutputPort("request").Eval(ctx)[0] == 1
    decision.GetMutableData().set_value(
        Decision(
            1,
            PickDecision("grasp", np.array([0.05, 0.0, 0.3]), (0, 1), planning_time=0.1, last_resort=True),
            5,
        )
    )
    t = 0.5
    while t < 12.0:
        t += 0.01
        sim.AdvanceTo(t)
        s = c.state(ctx)
        if not modes or modes[-1] != s.mode:
            modes.append(s.mode)
            grippers.append(c.GetOutputPort("gripper.position").Eval(ctx)[0])
    assert modes[:8] == ["approach", "close", "lift", "to_bin", "open", "home", "check", "wait"]
    assert grippers[modes.index("close")] == 0.0 and grippers[modes.index("home")] == pytest.approx(0.075)
    a = c.state(ctx).attempts[0]
    assert a["group"] == [0, 1] and a["held_width"] == pytest.approx(0.03) and a["end"] > a["start"]
    assert a["last_resort"] is True  # found with a robust planner's screen relaxed: recorded
    assert c.GetOutputPort("request").Eval(ctx)[0] == 2  # asked for the next image over the bin
    s = c.state(ctx)
    assert s.counter == 2 and s.retakes == 0  # unchanged: waits for the decision of that image
    assert s.robot_time == pytest.approx(a["end"] - a["start"], abs=0.02)


def test_a_changed_table_drops_the_decision_and_takes_a_new_image():
    """The next image is asked for when the jaws open over the bin (this cell's arm hides part
    of the table until it is nearly home); at the observe pose the controller asks for a check
    of that image, and when Perception answers that the table changed, the decision of that
    image is never waited for: a new image is asked for at once."""
    from pydrake.common.value import AbstractValue

    from mog_drake.planning.decision import PickDecision
    from mog_drake.systems.perception import Checked
    from mog_drake.systems.planner import Decision

    c, ctx, decision, sim, checked = _controller_with_fixed_inputs(with_check=True)
    sim.AdvanceTo(0.5)
    decision.GetMutableData().set_value(
        Decision(1, PickDecision("grasp", np.array([0.05, 0.0, 0.3]), (0,)), 5)
    )
    asked_at = None
    while c.state(ctx).mode != "check":
        sim.AdvanceTo(ctx.get_time() + 0.01)
        if asked_at is None and c.GetOutputPort("request").Eval(ctx)[0] == 2:
            asked_at = c.state(ctx).mode
    assert asked_at == "open" and c.GetOutputPort("check").Eval(ctx)[0] == 2
    # The decision of image 2 is ready, but the table changed: it must not be used.
    decision.GetMutableData().set_value(
        Decision(2, PickDecision("grasp", np.array([0.05, 0.0, 0.3]), (0,)), 5)
    )
    sim.AdvanceTo(ctx.get_time() + 0.2)
    assert c.state(ctx).mode == "check"  # no answer yet: the arm waits at the observe pose
    c.GetInputPort("checked").FixValue(ctx, AbstractValue.Make(Checked(2, True, 300)))
    sim.AdvanceTo(ctx.get_time() + 0.05)
    s = c.state(ctx)
    assert s.mode == "wait" and s.counter == 3 and s.retakes == 1 and len(s.attempts) == 1
    assert c.GetOutputPort("request").Eval(ctx)[0] == 3


def test_a_descent_pressed_past_the_guard_force_stops_and_backs_out():
    """The guarded descent: above the grasp the wrist's force is taken as zero; 50 N more on
    the way down (a plate on an object) stops the arm there, and it backs out with the jaws
    open, the attempt ended as stopped; a new image is asked for. Below the guard nothing
    happens."""
    from mog_drake.planning.decision import PickDecision
    from mog_drake.systems.planner import Decision

    c, ctx, decision, sim = _controller_with_fixed_inputs()
    force = c.GetInputPort("ur5.wrist_force").FixValue(ctx, np.array([3.0, -2.0, 10.0]))  # a bias
    sim.AdvanceTo(0.5)
    decision.GetMutableData().set_value(
        Decision(1, PickDecision("grasp", np.array([0.05, 0.0, 0.3]), (0,)), 5)
    )
    sim.AdvanceTo(0.6)
    s = c.state(ctx)
    assert s.mode == "approach"
    down = s.t_mode + s.plan["descend_at"]
    sim.AdvanceTo(down + 0.05)  # descending: the bias taken as zero
    np.testing.assert_allclose(c.state(ctx).force_zero, [3.0, -2.0, 10.0])
    force.GetMutableData().set_value(np.array([3.0, -2.0, 10.0 + 30.0]))  # under the 40 N guard
    sim.AdvanceTo(down + 0.1)
    assert c.state(ctx).mode == "approach"
    force.GetMutableData().set_value(np.array([3.0, -2.0, 10.0 + 50.0]))
    sim.AdvanceTo(down + 0.12)
    s = c.state(ctx)
    assert s.mode == "retreat" and s.gripper == OPEN_WIDTH  # the jaws still open
    stop = s.attempts[0]["stopped"]
    assert stop["force"] == pytest.approx(50.0) and stop["after"] >= s.plan["descend_at"]
    # It backs up the way it came (the first point of the retreat is where it stopped).
    q_stop = s.plan["approach"].value(stop["after"]).ravel()
    np.testing.assert_allclose(s.plan["retreat"].value(0.0).ravel(), q_stop, atol=1e-9)
    while c.state(ctx).mode == "retreat":
        sim.AdvanceTo(ctx.get_time() + 0.05)
    s = c.state(ctx)
    assert s.mode == "wait" and "end" in s.attempts[0] and "held_width" not in s.attempts[0]
    assert c.GetOutputPort("request").Eval(ctx)[0] == 2


def test_unreachable_grasps_are_skipped_and_three_in_a_row_end_the_run():
    """A grasp the arm cannot reach is recorded and the controller observes again (the planner
    will not repeat it); only three unreachable grasps in a row end the run."""
    from mog_drake.planning.decision import PickDecision
    from mog_drake.systems.planner import Decision

    c, ctx, decision, sim = _controller_with_fixed_inputs()
    sim.AdvanceTo(0.5)
    far = np.array([3.0, 0.0, 0.0])  # three metres from the base: out of the UR5's reach
    for k in (1, 2, 3):
        request = int(c.GetOutputPort("request").Eval(ctx)[0])
        decision.GetMutableData().set_value(
            Decision(request, PickDecision("grasp", far, (0,), planning_time=0.25), 4)
        )
        sim.AdvanceTo(ctx.get_time() + 0.05)
        s = c.state(ctx)
        assert len(s.skipped) == k and s.attempts == []
        assert "no arm configuration" in s.skipped[-1]["reason"] and s.skipped[-1]["grasp"] == far.tolist()
        if k < 3:
            assert s.mode == "wait" and c.GetOutputPort("request").Eval(ctx)[0] == request + 1
    assert s.mode == "done" and s.finished.startswith("unreachable grasp (3 in a row)")


def test_drop_pose_above_the_bin_retries_other_seeds_and_yaws(monkeypatch):
    """One failed solve of the drop pose (a poor seed) does not fail the attempt."""
    from mog_drake.errors import MogError
    from mog_drake.systems.motion import ArmMotion

    sc = Scenario()
    m = ArmMotion(sc.robot.base, sc.robot.max_joint_speed, sc.robot.max_joint_acceleration)
    real_ik, calls = m.ik, []

    def flaky(position, yaw, q_seed, **kw):
        calls.append(yaw)
        if len(calls) <= 2:
            raise MogError("no arm configuration reaches (simulated solver failure)")
        return real_ik(position, yaw, q_seed, **kw)

    monkeypatch.setattr(m, "ik", flaky)
    p = [sc.bin.center[0], sc.bin.center[1], 0.3]
    q = m.bin_ik(p, 0.4, (np.array(sc.robot.home), np.array(sc.robot.home)))
    assert len(calls) == 4 and calls[2] == pytest.approx(0.4 + np.pi / 2)  # then the half turn
    np.testing.assert_allclose(m.palm_pose(q).translation(), p, atol=5e-4)
    monkeypatch.setattr(m, "ik", lambda *a, **kw: (_ for _ in ()).throw(MogError("no")))
    with pytest.raises(MogError, match="drop pose above the bin"):
        m.bin_ik(p, 0.4, (np.array(sc.robot.home),))
