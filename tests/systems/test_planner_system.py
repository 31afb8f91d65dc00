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
