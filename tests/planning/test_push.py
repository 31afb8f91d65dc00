"""push-mog: consolidating pushes. The geometry of a push, its physics check, the planner's
rule (push only when the push and the grasp it sets up beat the grasp now), and a push
executed by the Controller on the simulated station, through the same ports as a grasp."""

import math

import numpy as np
import pytest
from conftest import make_scene

from mog_drake.geometry import GripperGeometry
from mog_drake.geometry.groups import adjacent_groups
from mog_drake.geometry.push import (
    MAX_PUSH,
    PUSH_GAP,
    Push,
    contact_distance,
    push_between,
    push_candidates,
    pusher_square,
)
from mog_drake.planning.config import PlannerSpec, PushConfig
from mog_drake.planning.picking import next_pick
from mog_drake.planning.planner import GraspPlanner
from mog_drake.planning.protocol import GraspResult

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def test_contact_distance_is_how_far_a_polygon_slides_before_it_touches():
    assert contact_distance(SQUARE, SQUARE + [3, 0], [1, 0]) == pytest.approx(2.0)
    assert contact_distance(SQUARE, SQUARE + [3, 0.5], [1, 0]) == pytest.approx(2.0)
    assert contact_distance(SQUARE, SQUARE + [3, 2], [1, 0]) == math.inf  # passes beside it
    assert contact_distance(SQUARE, SQUARE + [-3, 0], [1, 0]) == math.inf  # behind it
    assert contact_distance(SQUARE, SQUARE + [1, 0], [1, 0]) == pytest.approx(0.0)  # touching
    d = np.array([1.0, 1.0]) / math.sqrt(2)  # a corner meets a corner
    assert contact_distance(SQUARE, SQUARE + [2, 2], d) == pytest.approx(math.sqrt(2))


# Two thick bars side by side, 45 mm apart: no group at the 35 mm radius, and no grasp of one
# lifts the other.
BARS = [("thick_bar", 0.0, -0.0225, 0.0), ("thick_bar", 0.0, 0.0225, 0.0)]


def test_a_push_brings_an_object_to_push_gap_short_of_the_other_with_the_pusher_clear():
    scene = make_scene(BARS)
    polys = scene.polygons()
    g = GripperGeometry()
    p = push_between(polys, 0, 1, g)
    assert p is not None and (p.target, p.toward) == (0, 1)
    assert p.direction == pytest.approx([0.0, 1.0])
    # 45 mm between centres, 12 mm bars: 33 mm apart, pushed to PUSH_GAP short.
    assert p.distance == pytest.approx(0.033 - PUSH_GAP, abs=1e-6)
    moved = polys.polygon(0) + p.direction * p.distance
    assert contact_distance(moved, polys.polygon(1), p.direction) == pytest.approx(PUSH_GAP, abs=1e-6)
    # The pusher starts clear of the bar it pushes, and ends against it, moved.
    start = pusher_square(p.start, p.direction, g)
    assert contact_distance(start, polys.polygon(0), p.direction) > 0.005
    end = pusher_square(p.end, p.direction, g)
    assert contact_distance(end, moved, p.direction) == pytest.approx(0.0, abs=1e-6)


def test_no_push_through_a_third_object_or_beyond_max_push():
    blocked = make_scene([*BARS, ("thin_bar", 0.0, 0.0, 0.0)])  # a thin bar between them
    assert push_between(blocked.polygons(), 0, 1, GripperGeometry()) is None
    far = make_scene([("thick_bar", 0.0, -0.1, 0.0), ("thick_bar", 0.0, 0.1, 0.0)])
    assert push_between(far.polygons(), 0, 1, GripperGeometry()) is None  # 188 mm > MAX_PUSH
    assert MAX_PUSH < 0.188
    # A pusher that would start on a neighbour: the hexagon right behind bar 0.
    crowded = make_scene([*BARS, ("small_hexagon", 0.0, -0.045, 0.0)])
    pushes = push_candidates(crowded.polygons(), [0], GripperGeometry())
    assert all(p.toward != 1 for p in pushes)


def test_no_push_takes_the_object_or_the_pusher_into_a_keep_out_box():
    """The bin's walls (a keep-out box): a push whose object path or pusher sweep would enter
    it is refused, and the same push is made when the box lies clear of both."""
    polys = make_scene(BARS).polygons()
    g = GripperGeometry()
    p = push_between(polys, 0, 1, g)
    assert p is not None
    # The pusher starts behind bar 0 (y < p.start[1] + a plate): a box just behind it.
    behind = (-0.05, 0.05, p.start[1] - 0.03, p.start[1] - 0.005)
    assert push_between(polys, 0, 1, g, [behind]) is None
    beside = (0.02, 0.06, -0.05, 0.05)  # 2 cm to the side of the bars' 12 mm width
    assert push_between(polys, 0, 1, g, [beside]) == p


def test_adjacent_groups_join_objects_that_meet_end_to_end():
    """Two thin bars end to end (centres 53 mm apart) are no radius group; adjacent, they are."""
    scene = make_scene([("thin_bar", -0.0265, 0.0, 0.0), ("thin_bar", 0.0265, 0.0, 0.0), BARS[0]])
    w_g = GripperGeometry().w_g
    assert adjacent_groups(scene.polygons(), 0.007, w_g) == [(0, 1)]
    assert adjacent_groups(scene.polygons(), 0.001, w_g) == []


class ConsolidatingPhysics:
    """A test double of the physics check: a grasp lifts every group object whose outline
    comes within 7 mm of another's, or the first one alone (and so lifts a group only once
    it has been pushed together); a push moves its object along its line by its distance."""

    def __init__(self):
        self.pushes = []

    def check(self, scene, group, grasp):
        polys = scene.polygons()
        together = adjacent_groups(polys, 0.007, 1.0)
        lifted = next((list(g) for g in together if set(group) <= set(g)), [group[0]])
        return GraspResult(set(lifted) >= set(group), lifted=lifted)

    def push(self, scene, push, speed):
        from dataclasses import replace

        from mog_drake.scenes import SceneObject
        from mog_drake.sim.verifier import PushResult

        self.pushes.append(push)
        o = scene.objects[push.target]
        dx, dy = push.direction * push.distance
        objects = list(scene.objects)
        objects[push.target] = SceneObject(o.shape, o.x + dx, o.y + dy, o.theta)
        self.after = replace(scene, objects=objects)
        return PushResult(self.after, {push.target: push.distance})


def _decide(scene, pushes_left=5, **pushes):
    physics = ConsolidatingPhysics()
    planner = GraspPlanner(physics, PlannerSpec().grasp)
    d = next_pick(
        scene,
        planner,
        PlannerSpec(mode="push-mog", pushes=PushConfig(**pushes)),
        np.random.default_rng(0),
        pushes_left=pushes_left,
    )
    return d, physics


def test_push_mog_pushes_when_the_push_and_its_grasp_beat_the_grasp_now():
    """Two bars apart: a grasp now lifts 1 (in 6.5 s of robot time); a push (1.5 s and 0.54 s
    along its 27 mm) sets up a grasp of 2: 2 / 8.54 > 1 / 6.5, so it pushes. The decision
    carries the grasp that follows (found on the table the simulated push left), unless the
    arm is to look again after the push."""
    d, physics = _decide(make_scene(BARS))
    assert d.status == "push" and isinstance(d.push, Push)
    assert set(d.group) == {0, 1} and set(d.expected) == {0, 1} and d.now == 1
    assert d.grasp is not None and len(physics.pushes) >= 1
    assert ConsolidatingPhysics().check(physics.after, (0, 1), d.grasp).success
    d, _ = _decide(make_scene(BARS), then_grasp=False, push_time_s=3.1)
    assert d.status == "push" and d.grasp is None


def test_push_mog_grasps_when_pushing_does_not_pay_or_no_push_is_left():
    # Already together: the grasp now takes both.
    together = make_scene([("thick_bar", 0.0, -0.009, 0.0), ("thick_bar", 0.0, 0.009, 0.0)])
    d, physics = _decide(together)
    assert d.status == "grasp" and set(d.expected) == {0, 1} and physics.pushes == []
    assert d.lone == ""  # a grasp of two
    # Apart, but a push costs as much as 2 grasps: 2 / (13 + 6.5) < 1 / 6.5.
    d, physics = _decide(make_scene(BARS), push_time_s=13.0)
    assert d.status == "grasp" and physics.pushes == [] and d.lone == "not worth it"
    # Apart, but the grasp now lifts 1 and pushes are considered only below 1.
    d, physics = _decide(make_scene(BARS), below=1)
    assert d.status == "grasp" and physics.pushes == []
    # Apart, and the table's pushes are used up.
    d, physics = _decide(make_scene(BARS), pushes_left=0)
    assert d.status == "grasp" and physics.pushes == [] and d.lone == "out of pushes"
    # Farther apart than a push may go (pushes.reach, 12 cm).
    far = make_scene([("thick_bar", 0.0, -0.08, 0.0), ("thick_bar", 0.0, 0.08, 0.0)])
    d, physics = _decide(far)
    assert d.status == "grasp" and physics.pushes == [] and d.lone == "too far"
    # mog never pushes.
    planner = GraspPlanner(ConsolidatingPhysics(), PlannerSpec().grasp)
    d = next_pick(make_scene(BARS), planner, PlannerSpec(mode="mog"), pushes_left=5)
    assert d.status == "grasp"


def test_a_push_the_lookahead_found_to_pay_is_replayed_with_no_physics_while_its_objects_lie_still():
    """push-mog with the lookahead. The first decision grasps a pair (it lifts 2: no push is
    considered); the lookahead plans the rest (two bars apart) and finds that pushing one to
    the other pays. The next image shows those bars where they were: its decision is that
    push and the same grasp, with no push simulated and no physics check. Listed in the
    other order, the push is replayed in the new ids (Alg. 1's lone grasp, planned first for
    the bar the lookahead did not, is checked). With one bar 1 cm away from where it was,
    the push is simulated again."""
    from mog_drake.planning.decision import PaidPush
    from mog_drake.planning.lookahead import lookahead

    pair = [("thick_bar", 0.15, -0.009, 0.0), ("thick_bar", 0.15, 0.009, 0.0)]
    scene = make_scene([*pair, *BARS])
    spec = PlannerSpec(mode="push-mog")
    physics = ConsolidatingPhysics()
    planner = GraspPlanner(physics, spec.grasp)
    d = next_pick(scene, planner, spec, np.random.default_rng(0), failures=(), pushes_left=5)
    assert d.status == "grasp" and set(d.expected) == {0, 1} and physics.pushes == []
    memory = lookahead(scene, d, planner, spec, np.random.default_rng(1), pushes_left=5)
    paid = [f for f in memory if isinstance(f, PaidPush)]
    assert len(paid) == 1 and len(physics.pushes) >= 1

    def decide(bars):
        again = ConsolidatingPhysics()
        planner = GraspPlanner(again, spec.grasp)
        nd = next_pick(
            make_scene(bars), planner, spec, np.random.default_rng(2), failures=memory, pushes_left=5
        )
        return nd, again

    nd, again = decide(BARS)
    assert nd.status == "push" and again.pushes == [] and nd.physics_checks == 0
    assert nd.remembered_pushes == 1 and (nd.push.target, nd.push.toward) == (
        paid[0].push.target,
        paid[0].push.toward,
    )
    assert np.allclose(nd.grasp, paid[0].grasp) and set(nd.expected) == {0, 1}
    assert ConsolidatingPhysics().check(nd.after, (0, 1), nd.grasp).success
    assert not any(f is paid[0] for f in nd.failures)  # made now: not replayed again
    nd, again = decide(BARS[::-1])  # the lookahead's bar 0 is bar 1 now, and back
    assert nd.status == "push" and again.pushes == [] and nd.remembered_pushes == 1
    assert (nd.push.target, nd.push.toward) == (1 - paid[0].push.target, 1 - paid[0].push.toward)
    assert np.allclose(nd.grasp, paid[0].grasp)
    moved = [BARS[1], ("thick_bar", 0.0, -0.0325, 0.0)]
    nd, again = decide(moved)
    assert nd.status == "push" and len(again.pushes) >= 1 and nd.remembered_pushes == 0


def test_a_simulated_push_moves_its_object_where_the_geometry_said_on_a_table_with_friction():
    from mog_drake.scenario import Scenario
    from mog_drake.sim.verifier import DrakeVerifier

    sc = Scenario()
    v = DrakeVerifier(sc.verifier, physics=sc.gripper)
    scene = make_scene(BARS)
    p = push_between(scene.polygons(), 0, 1, v.gripper)
    r = v.push(scene, p, speed=0.05)
    assert r.error == ""
    bar = r.scene.objects[0]
    assert np.hypot(bar.x - 0.0, bar.y - (-0.0225 + p.distance)) < 0.003  # within 3 mm
    assert abs(bar.theta) < math.radians(5)
    assert r.moved.get(1, 0.0) < 0.001  # the other bar did not move


@pytest.mark.parametrize("then_grasp", [True, False])
def test_the_controller_pushes_on_the_station_then_grasps_the_pair(tmp_path, then_grasp):
    """push-mog end to end on the simulated station: the two bars 45 mm apart are pushed
    together (one push, the jaws closed at grasp height), then lifted together by one grasp:
    at once, where the planner's physics check left them, or after a new image."""
    from mog_drake.config import LatencyConfig
    from mog_drake.scenario import Scenario, SceneFile
    from mog_drake.systems.pick import run_pick

    make_scene(BARS).save(tmp_path / "bars.yaml")
    sc = Scenario(
        scene=SceneFile(file=str(tmp_path / "bars.yaml")),
        latency=LatencyConfig("fixed", perception_s=0.2, planning_s=1.0),
        time_limit=60.0,
    )
    sc.planner.mode = "push-mog"
    sc.planner.pushes.then_grasp = then_grasp
    run = run_pick(sc)
    assert len(run.pushes) == 1
    p = run.pushes[0]
    assert p["end"] > p["start"] and set(p["group"]) == {0, 1} and p["now"] == 1
    assert len(run.attempts) == 1 and run.attempts[0]["picked"] == 2
    assert run.attempts[0]["start"] >= p["end"]
    assert run.attempts[0].get("after_push", False) == then_grasp
    s = run.summary()
    assert s["pushes"] == 1 and s["push_gain"] == 1 and s["picked_pct"] == 100.0
    assert 0 < s["push_time_s"] < s["robot_time_s"]


def test_push_motions_stay_inside_the_hardware_safety_limits():
    """Every joint command of a push (down, along, up) passes the hardware station's
    SafetyMonitor with its default limits, and along the line the fingertips stay at grasp
    height; a push sent 5 cm below the table is refused by the same check."""
    from mog_drake.hardware.safety import SafetyLimits, SafetyMonitor
    from mog_drake.scenario import Scenario
    from mog_drake.systems.motion import ArmMotion

    sc = Scenario()
    motion = ArmMotion(sc.robot.base, sc.robot.max_joint_speed, sc.robot.max_joint_acceleration, sc.motion)
    monitor = SafetyMonitor(SafetyLimits(), sc.robot.base)
    push = push_between(make_scene(BARS).polygons(), 0, 1, GripperGeometry())
    plan = motion.push_plan(push, sc.robot.home, speed=0.05)
    for mode in ("push_approach", "push_line", "push_home"):
        traj = plan[mode]
        for t in np.linspace(0.0, traj.end_time(), 40):
            q = traj.value(t).ravel()
            assert monitor.check(q) == "", (mode, t)
    line = plan["push_line"]
    for t in np.linspace(0.0, line.end_time(), 20):
        tips = monitor.frames(line.value(t).ravel())
        assert 0.0 <= tips["left fingertip"][2] <= 0.006
    q_low = motion.ik([push.start[0], push.start[1], -0.05 + motion.finger_height], push.yaw, sc.robot.home)
    assert "palm" in monitor.check(q_low)  # outside the workspace box, whose floor is 35 mm up


def test_a_push_that_did_not_pay_is_not_simulated_again_while_nothing_moved():
    """Three pairs of lone bars, 20 cm apart; every grasp lifts one bar, pushed or not, so no
    push pays.
    The first decision simulates its two best pushes and remembers both; the next decision
    on the same table (its memory passed on) simulates the next two instead, and without a
    memory the same two again."""

    class NothingJoins(ConsolidatingPhysics):
        def check(self, scene, group, grasp):
            return GraspResult(len(group) == 1, lifted=[group[0]])

    scene = make_scene([(b[0], b[1] + x, b[2], b[3]) for x in (-0.2, 0.0, 0.2) for b in BARS])
    physics = NothingJoins()
    planner = GraspPlanner(physics, PlannerSpec().grasp)
    spec = PlannerSpec(mode="push-mog", pushes=PushConfig(checks=2))

    def decide(failures):
        physics.pushes = []
        d = next_pick(scene, planner, spec, np.random.default_rng(0), failures=failures, pushes_left=5)
        return d, [(p.target, p.toward) for p in physics.pushes]

    first, tried = decide(())
    assert first.status == "grasp" and len(tried) == 2 and first.remembered_pushes == 0
    second, tried_next = decide(first.failures)
    assert second.remembered_pushes == 2 and len(tried_next) == 2 and not set(tried) & set(tried_next)
    assert decide(None)[1] == tried
