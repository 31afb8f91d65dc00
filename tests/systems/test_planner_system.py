"""PlannerSystem: what it decides over successive scenes."""

import pytest


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


def test_after_a_miss_the_next_grasp_keeps_off_the_object_nearest_its_jaws():
    """A bar with a cube beside it, the first grasp's jaw 2.6 mm from the cube, seen again after
    it (a miss: in a stiff world, a plate that came down on the cube stops the arm). Without
    `LoopConfig.wary_neighbours` the next grasp puts a jaw 2.4 mm from the cube (only the
    missed jaws' own footprints are kept clear); with it the cube is suspected, and the next
    grasp keeps its jaws the first gap plus 2 mm off it."""
    import shapely
    from pydrake.common.value import AbstractValue
    from pydrake.systems.analysis import Simulator

    from mog_drake.config import LatencyConfig
    from mog_drake.planning.config import LoopConfig, PlannerSpec
    from mog_drake.planning.picking import SUSPECT_EXTRA
    from mog_drake.planning.planner import GraspPlanner, jaw_footprints
    from mog_drake.planning.protocol import GraspResult
    from mog_drake.scenario import Scenario
    from mog_drake.scenes import Scene, SceneObject, default_library
    from mog_drake.systems.messages import Perceived
    from mog_drake.systems.planner import PlannerSystem

    class LiftsAnything:
        def check(self, scene, group, grasp):
            return GraspResult(True, lifted=list(group))

    scene = Scene(
        [SceneObject("thick_bar", 0.0, 0.0, 0.3), SceneObject("small_yellow_cube", 0.0, -0.061, 0.0)],
        default_library(),
    )
    cube = shapely.Polygon(scene.polygon(1))

    def two_decisions(wary: bool):
        spec = PlannerSpec(loop=LoopConfig(wary_neighbours=wary))
        p = PlannerSystem(
            GraspPlanner(LiftsAnything(), Scenario().planner.grasp),
            spec,
            latency=LatencyConfig("fixed", 0.0, 0.0),
        )
        ctx = p.CreateDefaultContext()
        sim = Simulator(p, ctx)
        out = []
        for k in range(2):
            p.GetInputPort("scene").FixValue(ctx, AbstractValue.Make(Perceived(k, scene)))
            sim.AdvanceTo(ctx.get_time() + 0.02)
            d = p.GetOutputPort("decision").Eval(ctx)
            gap = min(shapely.Polygon(f).distance(cube) for f in jaw_footprints(d.decision.grasp))
            out.append((d.decision.group, gap, d.suspects))
        return out

    plain, wary = two_decisions(False), two_decisions(True)
    assert plain[0] == wary[0] and plain[0][0] == (0,) and 0.002 < plain[0][1] < 0.003
    margin = plain[0][1] + SUSPECT_EXTRA
    assert plain[1][0] == (0,) and plain[1][1] < margin and plain[1][2] == ()
    assert wary[1][2] == (("small_yellow_cube", 0.0, -0.061, pytest.approx(margin, abs=1e-4)),)
    assert wary[1][0] == (0,) and wary[1][1] >= margin - 1e-4
