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
