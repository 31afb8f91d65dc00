"""PlannerSystem: what it decides over successive scenes."""


def test_the_planner_gives_up_on_an_unrecognised_blob_after_three_grasps():
    from pydrake.common.value import AbstractValue
    from pydrake.systems.analysis import Simulator

    from mog_drake.config import LatencyConfig
    from mog_drake.planning.planner import GraspPlanner
    from mog_drake.planning.protocol import GraspResult
    from mog_drake.scenes import Scene, default_library
    from mog_drake.systems.messages import Perceived
    from mog_drake.systems.planner import PlannerSystem

    class LiftsAnything:  # a grasp always exists: only the planner system's count ends it
        def check(self, scene, group, grasp):
            return GraspResult(True, lifted=list(group))

    blob = {"vertices": [[0.0, 0.0], [0.02, 0.0], [0.02, 0.035], [0.0, 0.035]], "top": 0.03}
    p = PlannerSystem(GraspPlanner(LiftsAnything()), latency=LatencyConfig("fixed", 0.0, 0.0))  # no latency
    ctx = p.CreateDefaultContext()
    sim = Simulator(p, ctx)
    seen = []
    for k in range(5):
        scene = Scene([], default_library(), meta={"unrecognised_blobs": 1, "unrecognised": [blob]})
        p.GetInputPort("scene").FixValue(ctx, AbstractValue.Make(Perceived(k, scene)))
        sim.AdvanceTo(ctx.get_time() + 0.02)
        d = p.GetOutputPort("decision").Eval(ctx).decision
        seen.append((d.status, d.unrecognised))
    assert seen == [("grasp", True)] * 3 + [("unrecognised", False)] * 2


def test_after_a_grasp_that_took_nothing_the_jaws_stay_off_where_it_put_them():
    """The same bar seen again where it was after its grasp (a miss: something stopped the
    jaws or the bar slipped out): the next grasp's jaws keep off the footprints of the missed
    grasp's jaws. Avoiding the missed grasp alone (the recent grasps, within 5 mm) would try
    one a few millimetres from it, which lands where it did."""
    from pydrake.common.value import AbstractValue
    from pydrake.systems.analysis import Simulator

    from mog_drake.config import LatencyConfig
    from mog_drake.geometry import jaw_collision_free
    from mog_drake.planning.planner import GraspPlanner, jaw_footprints, jaw_obstacles
    from mog_drake.planning.protocol import GraspResult
    from mog_drake.scenario import Scenario
    from mog_drake.scenes import Scene, SceneObject, default_library
    from mog_drake.systems.messages import Perceived
    from mog_drake.systems.planner import PlannerSystem

    class LiftsAnything:
        def check(self, scene, group, grasp):
            return GraspResult(True, lifted=list(group))

    planner = GraspPlanner(LiftsAnything(), Scenario().planner.grasp)
    p = PlannerSystem(planner, latency=LatencyConfig("fixed", 0.0, 0.0))
    ctx = p.CreateDefaultContext()
    sim = Simulator(p, ctx)
    grasps = []
    for k in range(2):
        scene = Scene([SceneObject("thick_bar", 0.0, 0.0, 0.3)], default_library())
        p.GetInputPort("scene").FixValue(ctx, AbstractValue.Make(Perceived(k, scene)))
        sim.AdvanceTo(ctx.get_time() + 0.02)
        grasps.append(p.GetOutputPort("decision").Eval(ctx).decision.grasp)
    missed_at = jaw_obstacles(Scene([], default_library(), meta={"missed_jaws": jaw_footprints(grasps[0])}))
    assert jaw_collision_free(missed_at, grasps[1])[0]
    beside = planner.plan(scene, [0], avoid=[grasps[0]]).grasp  # the recent grasps avoided, no more
    assert not jaw_collision_free(missed_at, beside)[0]


def test_with_open_margin_the_decision_carries_the_robust_checks_jaws():
    """planner.robust.open_margin: the decision's opening is the inner opening of the robust
    check's jaws for its grasp (`RobustVerifier.jaws`: a lone bar, fitted with one margin a
    side); without the margin it is 0 (fully open)."""
    from dataclasses import replace

    from pydrake.common.value import AbstractValue
    from pydrake.systems.analysis import Simulator

    from mog_drake.config import LatencyConfig
    from mog_drake.planning.config import PlannerSpec, RobustConfig
    from mog_drake.planning.planner import GraspPlanner, fitted_opening
    from mog_drake.planning.protocol import GraspResult
    from mog_drake.planning.robust import RobustVerifier
    from mog_drake.scenario import Scenario
    from mog_drake.scenes import Scene, SceneObject, default_library
    from mog_drake.systems.messages import Perceived
    from mog_drake.systems.planner import PlannerSystem

    class LiftsAnything:
        def check(self, scene, group, grasp):
            return GraspResult(True, lifted=list(group))

    scene = Scene([SceneObject("thick_bar", 0.0, 0.0, 0.3)], default_library())
    openings = []
    for margin in (0.012, 0.0):
        robust = RobustConfig(screen=8, pose_sigma=0.003, yaw_sigma_deg=3, open_margin=margin)
        spec = replace(PlannerSpec(), robust=robust)
        planner = GraspPlanner(RobustVerifier(LiftsAnything(), [], robust), Scenario().planner.grasp)
        p = PlannerSystem(planner, spec, latency=LatencyConfig("fixed", 0.0, 0.0))
        ctx = p.CreateDefaultContext()
        p.GetInputPort("scene").FixValue(ctx, AbstractValue.Make(Perceived(0, scene)))
        Simulator(p, ctx).AdvanceTo(0.02)
        out = p.GetOutputPort("decision").Eval(ctx)
        assert out.decision.status == "grasp" and not out.decision.last_resort
        openings.append(out.opening)
        if margin:
            assert out.opening == planner.verifier.jaws(scene, out.decision.group, out.decision.grasp).w_g
            assert out.opening == fitted_opening(scene, [0], out.decision.grasp, planner.gripper, margin)
            assert 0.024 < out.opening < planner.gripper.w_g
        p.shutdown()
    assert openings[1] == 0.0
