"""ArmMotion: approaches timed, the path from the bin to the next grasp, the wrist, carrying."""

import logging

import numpy as np
import pytest

from mog_drake.scenario import Scenario


@pytest.mark.parametrize(
    "grasp",
    [
        [0.12752252028311523, 0.11852848728774064, 0.11453723216212808],
        [-0.09329131812729595, 0.002972219398899011, 0.4487989505128276],
        [-0.04591488584892374, -0.0872376541293426, 1.7951958020513104],  # v5, table 11
    ],
)
def test_approaches_the_clamped_spline_cannot_time_are_timed(grasp, caplog):
    """Grasps of picking sweeps (v4 tables 13 and 16, v5 table 11, sog) whose approach from
    the observe pose TOPP-RA could not time on the clamped C2 spline: the arm takes them on
    the shape-preserving path, and Drake's error for the expected failure is not logged."""
    from mog_drake.systems.motion import ArmMotion

    sc = Scenario()
    m = ArmMotion(sc.robot.base, sc.robot.max_joint_speed, sc.robot.max_joint_acceleration)
    with caplog.at_level(logging.INFO, logger="drake"):
        plan = m.pick_plan(np.array(grasp), sc.robot.home, sc.bin.center, sc.bin.depth)
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR]
    traj = plan["approach"]
    np.testing.assert_allclose(traj.value(0).ravel(), sc.robot.home, atol=1e-9)
    np.testing.assert_allclose(
        m.palm_pose(traj.value(traj.end_time()).ravel()).translation(), [*grasp[:2], 0.042], atol=5e-4
    )
    ts = np.linspace(0, traj.end_time(), 200)
    v = np.array([traj.EvalDerivative(t, 1).ravel() for t in ts])
    assert np.abs(v).max() <= sc.robot.max_joint_speed * 1.02


def test_from_the_bin_the_arm_goes_to_the_next_grasp_above_everything_and_within_the_safety_limits():
    """The approach from the drop pose over the bin (controller.return_home off): every
    command passes the hardware station's SafetyMonitor, and until the palm is above the
    grasp the fingertips stay above the hover height, less 2 cm: far above any prism."""
    from mog_drake.hardware.safety import SafetyLimits, SafetyMonitor
    from mog_drake.systems.motion import ArmMotion

    sc = Scenario()
    m = ArmMotion(sc.robot.base, sc.robot.max_joint_speed, sc.robot.max_joint_acceleration, sc.motion)
    monitor = SafetyMonitor(SafetyLimits(), sc.robot.base)
    rng = np.random.default_rng(7)
    z_hover = m.finger_clearance + sc.motion.hover
    for _ in range(12):
        first, then = rng.uniform([-0.2, -0.2, 0.0], [0.2, 0.2, np.pi], (2, 3))
        q_bin = m.pick_plan(first, sc.robot.home, sc.bin.center, sc.bin.depth)["home"].value(0.0).ravel()
        approach = m.pick_plan(then, q_bin, sc.bin.center, sc.bin.depth)["approach"]
        for t in np.linspace(0.0, approach.end_time(), 60):
            q = approach.value(t).ravel()
            assert monitor.check(q) == ""
            f = monitor.frames(q)
            if np.linalg.norm(f["palm"][:2] - then[:2]) > 0.01:
                assert min(f["left fingertip"][2], f["right fingertip"][2]) > z_hover - 0.02


def test_grasp_after_grasp_from_the_bin_the_wrist_does_not_wind_up():
    """v20's table 11 (sog), grasp after grasp, each approach from the last drop pose: chosen
    by the least turn alone, the wrist wound up by half turns until the drop pose's solver
    hit the joint's limit and flipped the arm, whose carry went 0.34 m below the table top.
    Every target's wrist now stays within half a turn of the observe pose's, and no planned
    move takes a link below LINK_FLOOR; a plan that would is refused."""
    from mog_drake.errors import MogError
    from mog_drake.systems.motion import LINK_FLOOR, ArmMotion

    sc = Scenario()
    home = np.array(sc.robot.home)
    m = ArmMotion(
        sc.robot.base,
        sc.robot.max_joint_speed,
        sc.robot.max_joint_acceleration,
        sc.motion,
        q_home=home,
    )
    grasps = [
        [-0.06, -0.006, 2.029], [-0.099, 0.038, 1.338], [-0.025, -0.021, 2.693], [-0.017, -0.053, 2.244],
        [0.131, -0.002, 2.176], [0.088, 0.022, 0.0], [0.081, 0.002, 0.0], [0.016, 0.094, 0.795],
        [-0.033, 0.047, 1.751], [0.112, -0.089, 0.337], [-0.094, -0.063, 1.795], [-0.009, -0.104, 1.231],
        [0.037, -0.026, 0.0],
    ]  # fmt: skip
    q = home
    for g in grasps * 2:
        plan = m.pick_plan(np.array(g), q, sc.bin.center, sc.bin.depth)
        q = plan["home"].value(0.0).ravel()  # the drop pose: the next approach starts there
        assert abs(q[5] - home[5]) <= np.pi + 1e-9
        assert plan["to_bin"].end_time() < 2.5  # no half-turn spin of the wrist on the way
    flipped = np.array([-1.91, 3.21, -4.58, 2.94, 1.57, 1.57])  # the flipped drop pose
    with pytest.raises(MogError, match=f"at least {LINK_FLOOR}"):
        m.pick_plan(np.array(grasps[0]), flipped, sc.bin.center, sc.bin.depth)
    # Whatever the arm did before, a target lies on the observe pose's branch: its IK starts
    # there (the start decides only the wrist's half turn).
    for g in grasps[:4]:
        from_home = m._above(g[:2], 0.16, (g[2], g[2] + np.pi), home)[1]
        np.testing.assert_allclose(
            m._above(g[:2], 0.16, (g[2], g[2] + np.pi), flipped)[1][:5], from_home[:5], atol=0.01
        )


def test_carrying_is_gentler_than_moving_empty():
    from mog_drake.config import MotionConfig
    from mog_drake.systems.motion import ArmMotion

    sc = Scenario()
    plans = {
        scale: ArmMotion(
            sc.robot.base,
            sc.robot.max_joint_speed,
            sc.robot.max_joint_acceleration,
            MotionConfig(carry_scale=scale),
        ).pick_plan(np.array([0.1, 0.1, 0.5]), sc.robot.home, sc.bin.center, sc.bin.depth)
        for scale in (1.0, 0.5)
    }
    for name in ("lift", "to_bin"):  # acceleration-limited: time grows like 1 / sqrt(scale)
        assert plans[0.5][name].end_time() > 1.3 * plans[1.0][name].end_time()
    for name in ("approach", "home"):
        assert plans[0.5][name].end_time() == pytest.approx(plans[1.0][name].end_time())
