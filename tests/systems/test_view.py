"""ArmView: when the arm hides none of the table left."""

import numpy as np
from conftest import make_scene

from mog_drake.scenario import Scenario


def test_arm_view_lets_the_next_image_be_taken_only_when_the_arm_hides_no_object_left():
    """At the observe pose the arm hides nothing; with the jaws just above an object it hides
    that object but not one across the table; carrying, it must first lift what it holds
    above the heights perception looks at."""
    from mog_drake.camera import camera_pose
    from mog_drake.station import rendered_intrinsics
    from mog_drake.systems.motion import ArmMotion
    from mog_drake.systems.pick import arm_view

    sc = Scenario()
    view = arm_view(sc, rendered_intrinsics(sc.camera))
    assert camera_pose(sc.camera) is not None
    near = make_scene([("large_hexagon", 0.10, 0.05, 0.0)])
    far = make_scene([("large_hexagon", -0.20, -0.30, 0.0)])

    def prisms(scene):
        return [(scene.polygon(0), scene.shape(0).height)]

    assert view(sc.robot.home) and view.clear_of(sc.robot.home, False, prisms(near))
    m = ArmMotion(sc.robot.base, sc.robot.max_joint_speed, sc.robot.max_joint_acceleration)
    plan = m.pick_plan(np.array([0.10, 0.12, 0.0]), sc.robot.home, sc.bin.center, sc.bin.depth)
    lift = plan["lift"]
    low, high = lift.value(0.0).ravel(), lift.value(lift.end_time()).ravel()
    assert not view(high, holding=True)  # above the table: it hides part of it
    assert not view.clear_of(high, False, prisms(near))  # 7 cm from the grasp, under the arm
    assert view.clear_of(high, False, prisms(far))
    assert view.clear_of(high, True, prisms(far))  # what it carries hangs high enough
    assert not view.clear_of(low, True, prisms(far))  # still at the grasp: it would be seen
    # Its jaws open over the bin, the arm hides none of the table (motion.bin_clearance): the
    # table can be checked from there (controller.return_home).
    for x, y, yaw in [(0.10, 0.12, 0.0), (-0.2, 0.2, 1.0), (0.2, -0.2, 2.0), (-0.25, -0.25, 0.5)]:
        q_bin = m.pick_plan(np.array([x, y, yaw]), sc.robot.home, sc.bin.center, sc.bin.depth)["home"]
        assert view(q_bin.value(0.0).ravel())
