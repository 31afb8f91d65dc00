import numpy as np

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
