import math

import numpy as np

from mog_drake.scenario import Scenario
from mog_drake.sim.ur5 import URDF_PATH, VELOCITY_LIMIT, forward_kinematics, ur5_urdf


def test_committed_urdf_is_the_generated_one():
    assert URDF_PATH.read_text() == ur5_urdf()


def test_urdf_kinematics_equal_the_dh_parameters():
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(URDF_PATH))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link"))
    plant.Finalize()
    assert plant.num_positions() == 6 and plant.num_actuators() == 6
    ctx = plant.CreateDefaultContext()
    for q in np.random.default_rng(0).uniform(-np.pi, np.pi, (10, 6)):
        plant.SetPositions(ctx, q)
        X = plant.CalcRelativeTransform(
            ctx, plant.world_frame(), plant.GetFrameByName("tool0")
        ).GetAsMatrix4()
        np.testing.assert_allclose(X, forward_kinematics(q), atol=1e-7)
    np.testing.assert_allclose(plant.GetVelocityUpperLimits(), VELOCITY_LIMIT)
    np.testing.assert_allclose(plant.GetPositionUpperLimits(), 2 * np.pi, rtol=1e-8)


def test_dh_reach_at_zero_is_the_published_one():
    # At q = 0 the UR5 stretches out along -x: |a2| + |a3| = 0.81725 m from the shoulder.
    T = forward_kinematics(np.zeros(6))
    assert abs(T[0, 3] + 0.81725) < 1e-9


def test_ik_reaches_the_workspace_corners():
    from mog_drake.systems.motion import ArmMotion

    sc = Scenario()
    m = ArmMotion(sc.robot.base, sc.robot.max_joint_speed, sc.robot.max_joint_acceleration)
    for x, y, yaw in [
        (-0.15, -0.15, 0.0),
        (0.15, -0.15, 1.0),
        (0.15, 0.15, 2.0),
        (-0.15, 0.15, 3.0),
        (0, 0, 0.5),
        # The table's far corners: the camera sees the whole table, so objects pushed there
        # are planned for.
        (0.29, 0.29, 0.8),
        (0.29, -0.29, 2.4),
        (-0.29, -0.29, 1.6),
    ]:
        plan = m.pick_plan(np.array([x, y, yaw]), sc.robot.home, sc.bin.center, sc.bin.depth)
        q = plan["approach"].value(plan["approach"].end_time()).ravel()
        X = m.palm_pose(q)
        np.testing.assert_allclose(X.translation(), [x, y, 0.042], atol=5e-4)
        # Palm z up; its x axis along the grasp yaw (modulo pi).
        R = X.rotation().matrix()
        assert R[2, 2] > 0.999
        assert abs(math.remainder(math.atan2(R[1, 0], R[0, 0]) - yaw, math.pi)) < 3e-3
        for name in ("approach", "lift", "to_bin", "home"):
            traj = plan[name]
            ts = np.linspace(0, traj.end_time(), 50)
            v = np.array([traj.EvalDerivative(t, 1).ravel() for t in ts])
            # Carrying objects (lift, to the bin), the arm keeps to a fraction of its limits.
            scale = m.config.carry_scale if name in ("lift", "to_bin") else 1.0
            assert np.abs(v).max() <= scale * sc.robot.max_joint_speed * 1.02
