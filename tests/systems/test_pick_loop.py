"""The pick loop never blocks: perception and planning run as jobs beside the Diagram, their
results become visible after their latency in simulated time, and a table that changed after
its image is planned again. These tests assert on simulated time and on what the systems
received, not on wall-clock speed."""

import time

import numpy as np
import pytest
from conftest import make_scene
from pydrake.systems.analysis import Simulator

from mog_drake.config import LatencyConfig
from mog_drake.planning.protocol import GraspResult
from mog_drake.scenario import Scenario, SceneFile
from mog_drake.systems.jobs import CPU, WALL, Worker, clock_of
from mog_drake.systems.pick import MakePickDiagram


class LiftsAnything:
    """A verifier that promises every grasp: planning costs no physics."""

    def check(self, scene, group, grasp):
        return GraspResult(True, lifted=list(group))


def _diagram(tmp_path, latency=None, objects=None, mode="sog", return_home=False, **planner):
    truth = make_scene(objects or [("large_hexagon", 0.05, -0.10, 0.3), ("blue_quad", -0.05, 0.12, 0.9)])
    truth.save(tmp_path / "scene.yaml")
    sc = Scenario(scene=SceneFile(file=str(tmp_path / "scene.yaml")), latency=latency or LatencyConfig())
    sc.planner.mode = mode
    sc.controller.return_home = return_home
    for k, v in planner.items():
        setattr(sc.planner, k, v)
    parts = MakePickDiagram(sc, verifier=LiftsAnything())
    d = parts.diagram
    sim = Simulator(d)
    return sc, d, parts, sim


def _close(parts):
    parts.perception.shutdown()
    parts.planner.shutdown()


def test_a_planner_slowed_by_2_s_does_not_delay_the_controllers_updates(tmp_path, monkeypatch):
    """Every plan takes 2 s of wall time. The controller still updates every period of
    simulated time while it runs; each decision becomes visible 2 s or more after its scene;
    and the second plan ran while the arm carried and returned: the arm waited for it less
    than the 2 s it took."""
    import mog_drake.systems.planner as planner_module

    real = planner_module.next_pick

    def slow(*a, **kw):
        time.sleep(2.0)
        return real(*a, **kw)

    monkeypatch.setattr(planner_module, "next_pick", slow)
    sc, d, parts, sim = _diagram(tmp_path)
    ctx = sim.get_mutable_context()
    c = parts.controller
    cctx = c.GetMyContextFromRoot(ctx)
    pctx = parts.planner.GetMyContextFromRoot(ctx)
    period = sc.controller.period
    lags, decisions = [], {}
    try:
        while ctx.get_time() < 20.0 and len(c.state(cctx).attempts) < 2:
            sim.AdvanceTo(ctx.get_time() + period)
            lags.append(ctx.get_time() - c.state(cctx).t_last)
            dec = parts.planner.GetOutputPort("decision").Eval(pctx)
            decisions.setdefault(dec.counter, dec)
    finally:
        _close(parts)
    s = c.state(cctx)
    assert len(s.attempts) == 2 and max(lags) <= period + 1e-9  # never a missed update
    for k in (1, 2):
        assert decisions[k].t_visible - decisions[k].t_request >= 2.0 - 1e-9
    # The second plan started before the arm was back at the observe pose (its image was
    # taken on the way to the bin), so the arm waited for it less than the 2 s it took.
    assert decisions[2].t_request < s.attempts[0]["end"]
    second_wait = s.wait_planning - (decisions[1].t_visible - decisions[1].t_request)
    assert second_wait < 1.0
    assert s.retakes == 0  # the arm over the bin in that image is no change of the table


def test_results_become_visible_only_after_their_latency(tmp_path):
    """Fixed latencies: a scene 0.3 s after its image, a decision 2.0 s after its scene (to
    the controller's period), and the arm idle for both before the first grasp."""
    latency = LatencyConfig("fixed", perception_s=0.3, planning_s=2.0)
    sc, d, parts, sim = _diagram(tmp_path, latency)
    ctx = sim.get_mutable_context()
    c, p, pl = parts.controller, parts.perception, parts.planner
    seen = {}
    try:
        while ctx.get_time() < 4.0:
            sim.AdvanceTo(ctx.get_time() + sc.controller.period)
            scene = p.GetOutputPort("scene").Eval(p.GetMyContextFromRoot(ctx))
            dec = pl.GetOutputPort("decision").Eval(pl.GetMyContextFromRoot(ctx))
            seen.setdefault(("scene", scene.counter), (ctx.get_time(), scene))
            seen.setdefault(("decision", dec.counter), (ctx.get_time(), dec))
    finally:
        _close(parts)
    t_scene, scene = seen[("scene", 1)]
    t_dec, dec = seen[("decision", 1)]
    period = sc.controller.period
    assert scene.t_visible - scene.t_request == pytest.approx(0.3, abs=period + 1e-9)
    assert scene.t_visible >= scene.t_request + 0.3 - 1e-9 and t_scene >= scene.t_visible
    assert dec.t_request >= scene.t_visible - 1e-9
    assert dec.t_visible - dec.t_request == pytest.approx(2.0, abs=period + 1e-9)
    s = c.state(c.GetMyContextFromRoot(ctx))
    # Each hand-over (scene to planner, decision to controller) takes up to one period; the
    # first image waits 0.1 s more, for a second frame that shows the table at rest.
    assert s.wait_perception == pytest.approx(0.1 + 0.3, abs=3 * period)
    assert s.wait_planning == pytest.approx(2.0, abs=3 * period)
    assert s.attempts and s.attempts[0]["start"] >= dec.t_visible - 1e-9


def _spin(seconds):
    """Busy for ``seconds`` of this thread's CPU time."""
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass
    return "spun"


def test_cpu_latency_counts_the_jobs_cpu_time_not_its_wall_time():
    """A job that sleeps 0.3 s costs no CPU time: with the ``cpu`` clock it is visible as soon
    as it is done; one that computes 0.2 s is not visible 0.1 s of simulated time after its
    request, and is 0.25 s after it (the collecting event waits for it, as in simulation)."""

    assert clock_of(LatencyConfig("cpu")) is CPU and clock_of(LatencyConfig()) is WALL
    worker = Worker("test", CPU)
    try:
        sleeper = worker.submit(time.sleep, 0.3, t_request=0.0, counter=1)
        assert sleeper.visible(0.05, None, block=True)
        assert sleeper.wall_time() >= 0.3 and sleeper.cpu_time() < 0.05
        spinner = worker.submit(_spin, 0.2, t_request=1.0, counter=2)
        assert not spinner.visible(1.1, None, block=True)
        assert spinner.visible(1.25, None, block=True)
        assert spinner.result() == "spun" and 0.2 <= spinner.cpu_time() < 0.25
    finally:
        worker.shutdown()
    wall = Worker("test", WALL)
    try:
        sleeper = wall.submit(time.sleep, 0.3, t_request=0.0, counter=1)
        assert not sleeper.visible(0.05, None, block=True)
        assert sleeper.visible(0.5, None, block=True)
    finally:
        wall.shutdown()


def _spin_then(seconds, got=None):
    """Busy for ``seconds`` of CPU, then returns ``got``."""
    _spin(seconds)
    return got


@pytest.mark.parametrize("planning_s,expect", [(0.5, "used"), (6.0, "dropped")])
def test_each_attempt_records_whether_the_lookaheads_memory_was_in_time(tmp_path, planning_s, expect):
    """mog, three objects apart, fixed latencies. A lookahead of 0.5 s is visible when the
    next image is planned ("used"); one of 6 s is not, and is dropped. Either way the plan of
    the second image is visible its own latency after its request."""
    latency = LatencyConfig("fixed", perception_s=0.1, planning_s=planning_s)
    objects = [
        ("large_hexagon", 0.05, -0.10, 0.3),
        ("blue_quad", -0.12, 0.12, 0.9),
        ("red_triangle", 0.15, 0.1, 0.2),
    ]
    sc, d, parts, sim = _diagram(tmp_path, latency, objects, mode="mog")
    ctx = sim.get_mutable_context()
    c, pl = parts.controller, parts.planner
    decisions = {}
    try:
        while ctx.get_time() < 40.0 and len(c.state(c.GetMyContextFromRoot(ctx)).attempts) < 2:
            sim.AdvanceTo(ctx.get_time() + 0.05)
            dec = pl.GetOutputPort("decision").Eval(pl.GetMyContextFromRoot(ctx))
            decisions.setdefault(dec.counter, dec)
    finally:
        _close(parts)
    attempts = c.state(c.GetMyContextFromRoot(ctx)).attempts
    assert attempts[0]["lookahead"] == "" and attempts[1]["lookahead"] == expect
    second = decisions[max(decisions)]
    assert second.t_visible - second.t_request == pytest.approx(planning_s, abs=0.06)


def test_a_changed_table_forces_a_new_plan(tmp_path):
    """After the image taken over the bin, an object on the table is moved 5 cm (as if
    knocked by the lift). Perception's check, made over the bin once the jaws have opened,
    finds the change, the decision of that image is dropped, a new image is taken there and
    planned from, and the next grasp is of the object where it now lies."""
    from pydrake.math import RigidTransform

    objects = [
        ("large_hexagon", 0.05, -0.10, 0.3),
        ("blue_quad", -0.05, 0.12, 0.9),
        ("red_triangle", 0.12, 0.1, 0.2),
    ]
    latency = LatencyConfig("fixed", perception_s=0.2, planning_s=0.5)
    sc, d, parts, sim = _diagram(tmp_path, latency, objects)
    ctx = sim.get_mutable_context()
    c = parts.controller
    cctx = c.GetMyContextFromRoot(ctx)
    handles = parts.handles
    plant = handles.plant
    pctx = plant.GetMyContextFromRoot(ctx)
    moved, scenes = None, {}
    p_sys = parts.perception
    try:
        while ctx.get_time() < 30.0 and len(c.state(cctx).attempts) < 2:
            sim.AdvanceTo(ctx.get_time() + sc.controller.period)
            seen = p_sys.GetOutputPort("scene").Eval(p_sys.GetMyContextFromRoot(ctx))
            scenes.setdefault(seen.counter, seen)
            s = c.state(cctx)
            if moved is None and s.mode == "open" and s.requested == 2:
                # The first attempt picked one object; move one still on the table.
                for i, body in handles.bodies.items():
                    X = plant.EvalBodyPoseInWorld(pctx, body)
                    if X.translation()[2] < 0.05 and abs(X.translation()[1]) < 0.3:
                        p = X.translation() + [0.0, -0.05 if X.translation()[1] > 0 else 0.05, 0.0]
                        plant.SetFreeBodyPose(pctx, body, RigidTransform(X.rotation(), p))
                        moved = (i, p)
                        break
    finally:
        _close(parts)
    s = c.state(cctx)
    assert moved is not None and s.retakes == 1 and len(s.attempts) == 2
    assert not scenes[2].retake and scenes[3].retake  # image 3 retakes image 2
    # Image 2 saw the object where it was; the retaken image 3 sees it where it now lies.
    i, p = moved
    shape = objects[i][0]
    near = [np.hypot(o.x - p[0], o.y - p[1]) for o in scenes[3].scene.objects if o.shape == shape]
    assert near and min(near) < 0.005
    before = [np.hypot(o.x - p[0], o.y - p[1]) for o in scenes[2].scene.objects if o.shape == shape]
    assert min(before) > 0.04


@pytest.mark.parametrize("return_home", [False, True])
def test_the_arm_goes_from_the_bin_to_the_next_grasp_unless_told_to_return_home(tmp_path, return_home):
    """With the jaws open over the bin, where the arm hides none of the table, the table is
    checked from there and the next grasp starts there: no trip to the observe pose (its
    1.4 s saved). With controller.return_home, the paper's cycle: back to the observe pose
    first. Either way the second grasp is of the second object."""
    latency = LatencyConfig("fixed", perception_s=0.1, planning_s=0.1)
    sc, d, parts, sim = _diagram(tmp_path, latency, return_home=return_home)
    ctx = sim.get_mutable_context()
    c = parts.controller
    cctx = c.GetMyContextFromRoot(ctx)
    modes, q_second = [], None
    try:
        while ctx.get_time() < 30.0 and len(c.state(cctx).attempts) < 2:
            sim.AdvanceTo(ctx.get_time() + sc.controller.period)
            s = c.state(cctx)
            if not modes or modes[-1] != s.mode:
                modes.append(s.mode)
        s = c.state(cctx)
        q_second = s.plan["approach"].value(0.0).ravel()
        # Where the arm must return after all (it hides the table over the bin), it returns
        # to the observe pose, wherever the attempt started.
        back = s.plan["home"]
        np.testing.assert_allclose(back.value(back.end_time()).ravel(), sc.robot.home, atol=1e-9)
    finally:
        _close(parts)
    first = modes[modes.index("open") :]
    assert len(s.attempts) == 2 and s.attempts[1]["shapes"] != s.attempts[0]["shapes"]
    if return_home:
        assert first[:4] == ["open", "home", "check", "wait"]
        np.testing.assert_allclose(q_second, sc.robot.home, atol=1e-9)
    else:
        assert first[:3] == ["open", "check", "wait"] and "home" not in modes
        assert np.abs(q_second - np.asarray(sc.robot.home)).max() > 0.1  # it starts over the bin
        assert s.attempts[0]["end"] < s.attempts[1]["start"]


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


def test_the_change_check_sees_moved_and_uncovered_objects_not_a_millimetre(tmp_path):
    """Perceiver.changed_pixels between two depth images: the same table gives 0; a hexagon
    moved 1 mm gives 0 (its outline shifts by a pixel: no new plan for that); moved 6 mm,
    hundreds; an object found where the first image saw the arm over the table counts too."""
    from mog_drake.camera import camera_pose
    from mog_drake.station import MakeStation, render_still

    def depth_of(x):
        scene = make_scene([("large_hexagon", x, 0.05, 0.3), ("blue_quad", -0.1, -0.1, 0.0)])
        scene.save(tmp_path / "t.yaml")
        sc = Scenario(scene=SceneFile(file=str(tmp_path / "t.yaml")))
        d, h = MakeStation(sc)
        return sc, h, np.array(render_still(sc, d)[1])

    sc, h, d0 = depth_of(0.05)
    perceiver = sc.perceiver()
    args = (camera_pose(sc.camera), h.camera_intrinsics)
    assert perceiver.changed_pixels(d0, d0.copy(), *args) == 0
    assert perceiver.changed_pixels(d0, depth_of(0.051)[2], *args) == 0
    assert perceiver.changed_pixels(d0, depth_of(0.056)[2], *args) > 100
    armed = d0.copy()
    rows, cols = np.nonzero(np.abs(d0 - 0.77) < 0.002)  # the hexagon's top (0.03 m high)
    armed[rows, cols] = 0.3  # something 0.5 m above the table hid it
    assert perceiver.changed_pixels(armed, d0, *args) > 100
    assert perceiver.changed_pixels(armed, d0, *args, still=True) == 0  # not a motion: unknown


def test_an_object_grasped_three_times_in_vain_is_given_up_and_the_run_ends(tmp_path, monkeypatch):
    """A grasp that the physics check trusts and the world keeps failing is not tried until
    the time limit. Here every planned grasp lands 6 cm beside its object (it closes on air),
    as a wrongly perceived pose would: the planner tallies the object's failures across
    images, whose ids differ, and after MAX_MISSES of them it plans that object no more. With
    nothing else on the table, the run ends "gave_up" with the object left in view."""
    import mog_drake.systems.planner as planner_module
    from mog_drake.planning.picking import MAX_MISSES

    real = planner_module.next_pick
    excluded = []

    def beside(*a, **kw):
        excluded.append(list(kw.get("exclude", ())))
        d = real(*a, **kw)
        if d.grasp is not None:
            d.grasp = d.grasp + np.array([0.0, 0.06, 0.0])
        return d

    monkeypatch.setattr(planner_module, "next_pick", beside)
    sc, d, parts, sim = _diagram(tmp_path, objects=[("large_hexagon", 0.05, -0.10, 0.3)])
    ctx = sim.get_mutable_context()
    c = parts.controller
    cctx = c.GetMyContextFromRoot(ctx)
    try:
        while ctx.get_time() < 120.0 and c.state(cctx).mode != "done":
            sim.AdvanceTo(ctx.get_time() + 0.25)
    finally:
        _close(parts)
    s = c.state(cctx)
    assert s.finished == "gave_up"
    assert len(s.attempts) == MAX_MISSES  # not one more
    assert excluded[:MAX_MISSES] == [[]] * MAX_MISSES and excluded[-1] == [0]
    # The object was never taken: it is still on the table, near where it was (jaws closing
    # 6 cm beside it nudge it, by 2-4 cm over the three misses).
    plant = parts.handles.plant
    p = plant.EvalBodyPoseInWorld(plant.GetMyContextFromRoot(ctx), parts.handles.bodies[0]).translation()
    assert np.hypot(p[0] - 0.05, p[1] + 0.10) < 0.06 and abs(p[2]) < 0.01


def test_a_lookahead_queued_behind_another_on_the_cpu_clock_carries_that_wait_in_its_latency():
    """On the CPU clock a job's time counts from its own start. A lookahead requested at 0.1,
    queued on its thread behind one requested at 0 that spins 0.3 s, starts where that one
    ended in simulated time, and that wait is latency: it is visible at its request plus the
    wait plus its own CPU time. On the wall clock the queueing is in its time already."""
    a = Worker("ahead", CPU)
    try:
        first = a.submit(_spin_then, 0.3, "first", t_request=0.0, counter=1)
        second = a.submit(_spin_then, 0.2, "second", t_request=0.1, counter=2)
        assert second.result() == "second"
        assert second.waited() == pytest.approx(first.cpu_time() - 0.1) and second.waited() > 0.19
        assert second.latency() == pytest.approx(second.cpu_time() + second.waited())
        end = 0.1 + second.latency()
        assert not second.visible(end - 0.05, None, block=True)
        assert second.visible(end + 1e-6, None, block=True)
    finally:
        a.shutdown()
    w = Worker("ahead", WALL)
    try:
        w.submit(_spin_then, 0.3, "first", t_request=0.0, counter=1)
        assert w.submit(_spin_then, 0.01, "second", t_request=0.1, counter=2).waited() == 0.0
    finally:
        w.shutdown()
