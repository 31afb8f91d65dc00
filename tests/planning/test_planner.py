import math

import numpy as np
import pytest
from conftest import make_scene

from mog_drake.errors import MogError
from mog_drake.geometry import evaluate_grasps, gen_grasp_cands, rank_grasp_cands
from mog_drake.geometry.polygon import axis_gap
from mog_drake.planning.config import LoopConfig, PlannerSpec
from mog_drake.planning.planner import METHODS, GraspConfig, GraspPlanner
from mog_drake.planning.protocol import GraspResult
from mog_drake.scenes import row_scene


class FakeVerifier:
    """Records every grasp it is asked about; succeeds only on the grasps in ``good``."""

    def __init__(self, good=()):
        self.good = [np.asarray(g) for g in good]
        self.asked = []

    def check(self, scene, group, grasp):
        self.asked.append(np.asarray(grasp).copy())
        ok = any(np.allclose(grasp, g) for g in self.good)
        return GraspResult(ok, lifted=list(group) if ok else [])


@pytest.fixture
def scene():
    return row_scene(3, np.random.default_rng(1))


def _figures(scene):
    polys = scene.polygons()
    cands = gen_grasp_cands(polys, scene.group)
    return cands, evaluate_grasps(polys, scene.group, cands)


def _index(cands, g):
    return int(np.flatnonzero(np.all(np.isclose(cands, g), axis=1))[0])


def test_rand_fil_phys_never_tests_a_filtered_candidate(scene):
    cands, ev = _figures(scene)
    v = FakeVerifier()  # nothing succeeds: every admissible candidate gets tested
    res = GraspPlanner(v, GraspConfig("rand-fil-phys")).plan(scene, scene.group, np.random.default_rng(0))
    tested = [_index(cands, g) for g in v.asked]
    assert len(tested) == res.tested == int(ev.passed.sum()) > 0
    assert all(ev.passed[i] for i in tested)
    assert not res.found


def test_rank_phys_tests_in_ranked_order_without_filter(scene):
    cands, ev = _figures(scene)
    v = FakeVerifier()
    res = GraspPlanner(v, GraspConfig("rank-phys", max_physics=40)).plan(scene, scene.group)
    tested = [_index(cands, g) for g in v.asked]
    assert tested == list(rank_grasp_cands(ev)[:40]) and res.tested == 40
    assert any(not ev.passed[i] for i in tested)  # no filter: rejected candidates are simulated too


def test_gp_stops_at_first_success_in_ranked_filtered_order(scene):
    cands, ev = _figures(scene)
    admissible = [int(i) for i in rank_grasp_cands(ev) if ev.passed[i]]
    assert len(admissible) >= 3
    v = FakeVerifier(good=[cands[admissible[2]]])
    res = GraspPlanner(v, GraspConfig("gp")).plan(scene, scene.group)
    assert [_index(cands, g) for g in v.asked] == admissible[:3]
    assert res.found and res.tested == 3 and np.allclose(res.grasp, cands[admissible[2]])
    assert set(res.times) == {"candidates", "filter", "rank", "physics", "total"}


def test_random_methods_are_seeded(scene):
    runs = []
    for seed in (5, 5, 6):
        v = FakeVerifier()
        GraspPlanner(v, GraspConfig("rand-phys", max_physics=10)).plan(
            scene, scene.group, np.random.default_rng(seed)
        )
        runs.append(np.array(v.asked))
    assert np.array_equal(runs[0], runs[1]) and not np.array_equal(runs[0], runs[2])
    with pytest.raises(MogError, match="seeded"):
        GraspPlanner(FakeVerifier(), GraspConfig("rand-phys")).plan(scene, scene.group)


def test_single_mode_plans_for_one_object(scene):
    res = GraspPlanner(FakeVerifier(), GraspConfig("single")).plan(
        scene, scene.group, np.random.default_rng(2)
    )
    assert len(res.group) == 1 and res.group[0] in scene.group


def test_unknown_method_refused():
    with pytest.raises(MogError, match="unknown planner method 'magic'"):
        GraspConfig("magic")
    assert set(METHODS) >= {"gp", "rand-phys", "rank-phys", "rand-fil-phys"}


def test_gp_grasp_is_confirmed_by_physics():
    from mog_drake.sim.verifier import row_verifier

    scene = make_scene(
        [("thick_bar", -0.012, 0.0, math.pi / 2), ("small_yellow_cube", 0.010, 0.002, 0.1)], group=(0, 1)
    )
    res = GraspPlanner(row_verifier()).plan(scene, (0, 1))
    assert res.found and res.tested >= 1
    again = row_verifier().check(scene, (0, 1), res.grasp)
    assert again.success and again.lifted == [0, 1]


def test_next_pick_tries_largest_groups_first_and_reports_clear():
    from mog_drake.planning.picking import next_pick
    from mog_drake.scenes import Scene

    # Three bars in a tight row (one group of 3) and a cube far away (a single).
    scene = make_scene(
        [
            ("thin_bar", -0.012, 0.0, math.pi / 2),
            ("thin_bar", 0.0, 0.0, math.pi / 2),
            ("thin_bar", 0.012, 0.0, math.pi / 2),
            ("small_yellow_cube", 0.15, 0.15, 0.0),
        ]
    )
    v = FakeVerifier()  # nothing lifts: every group is tried, largest first
    d = next_pick(scene, GraspPlanner(v, GraspConfig("gp")))
    assert d.status == "no_grasp"
    assert [p.group for p in d.plans][0] == (0, 1, 2)
    assert [len(p.group) for p in d.plans] == sorted((len(p.group) for p in d.plans), reverse=True)
    assert next_pick(Scene([], scene.library), GraspPlanner(v)).status == "table_clear"


def test_next_pick_groups_by_the_conditions_when_asked():
    from mog_drake.planning.picking import next_pick

    # Four bars 20 mm apart across the closing axis: the radius groups three of them at most;
    # the conditions group all four, and that group is planned first.
    scene = make_scene([("thin_bar", 0.02 * k, 0.0, math.pi / 2) for k in range(4)])
    v = FakeVerifier()
    assert next_pick(scene, GraspPlanner(v), PlannerSpec(loop=LoopConfig(last_resort=False))).plans[
        0
    ].group == (0, 1, 2)
    d = next_pick(
        scene, GraspPlanner(v), PlannerSpec(loop=LoopConfig(grouping="conditions", last_resort=False))
    )
    assert d.plans[0].group == (0, 1, 2, 3) and [p.group for p in d.plans][1:] == [(0,), (1,), (2,), (3,)]
    with pytest.raises(MogError, match="grouping must be one of"):
        next_pick(scene, GraspPlanner(v), PlannerSpec(loop=LoopConfig(grouping="nearest")))


def test_next_pick_single_object_mode_plans_single_objects():
    from mog_drake.planning.picking import next_pick

    scene = make_scene([("thin_bar", -0.012, 0.0, math.pi / 2), ("thin_bar", 0.0, 0.0, math.pi / 2)])

    class LiftsAnything(FakeVerifier):
        def check(self, scene, group, grasp):
            self.asked.append(tuple(group))
            return GraspResult(True, lifted=list(group))

    v = LiftsAnything()
    d = next_pick(scene, GraspPlanner(v), PlannerSpec(mode="sog"), rng=np.random.default_rng(0))
    assert d.status == "grasp" and len(d.group) == 1 and all(len(g) == 1 for g in v.asked)
    with pytest.raises(MogError, match="mode"):
        next_pick(scene, GraspPlanner(v), PlannerSpec(mode="both"))


def test_unrecognised_blobs_are_not_a_clear_table():
    from mog_drake.planning.picking import next_pick
    from mog_drake.scenes import Scene

    empty = Scene([], make_scene([]).library, meta={"unrecognised_blobs": 1})
    assert next_pick(empty, GraspPlanner(FakeVerifier())).status == "unrecognised"


def test_unrecognised_blobs_left_alone_are_planned_as_prisms_of_their_outline():
    from mog_drake.planning.picking import next_pick, unrecognised_scene
    from mog_drake.scenes import Scene

    c, s = math.cos(0.5), math.sin(0.5)
    rect = np.array([[-0.01, -0.0175], [0.01, -0.0175], [0.01, 0.0175], [-0.01, 0.0175]]) @ [[c, s], [-s, c]]
    blobs = [
        {"vertices": (rect + [0.05, 0.02]).tolist(), "top": 0.035},
        {"vertices": [[0.0, 0.0], [0.01, 0.0], [0.02, 0.0]], "top": 0.01},  # no area: dropped
    ]
    empty = Scene([], make_scene([]).library, meta={"unrecognised_blobs": 2, "unrecognised": blobs})
    as_prisms = unrecognised_scene(empty)
    assert len(as_prisms) == 1 and as_prisms.shape(0).height == 0.035
    assert np.allclose(sorted(map(tuple, as_prisms.polygon(0))), sorted(map(tuple, rect + [0.05, 0.02])))
    assert "unrecognised" not in " ".join(empty.library.shapes)  # the perceived library is untouched

    class LiftsAnything(FakeVerifier):
        def check(self, scene, group, grasp):
            self.asked.append((scene.shape(group[0]).height, tuple(group)))
            return GraspResult(True, lifted=list(group))

    v = LiftsAnything()
    d = next_pick(empty, GraspPlanner(v))
    assert d.status == "grasp" and d.unrecognised and d.group == (0,) and v.asked[0] == (0.035, (0,))
    assert np.linalg.norm(d.grasp[:2] - [0.05, 0.02]) < 0.02
    assert next_pick(empty, GraspPlanner(FakeVerifier())).status == "unrecognised"  # nothing lifts
    assert next_pick(empty, GraspPlanner(v), grasp_unrecognised=False).status == "unrecognised"


@pytest.mark.parametrize("vary_axis", [False, True])
def test_a_plan_skipping_what_an_earlier_one_tested_goes_on_where_it_stopped(scene, vary_axis):
    whole = FakeVerifier()
    GraspPlanner(whole, GraspConfig("gp", max_physics=5, vary_axis=vary_axis)).plan(scene, scene.group)
    v = FakeVerifier()
    first = GraspPlanner(v, GraspConfig("gp", max_physics=2, vary_axis=vary_axis)).plan(scene, scene.group)
    GraspPlanner(v, GraspConfig("gp", max_physics=3, vary_axis=vary_axis)).plan(
        scene, scene.group, skip=first.tested_indices
    )
    assert len(whole.asked) == 5 and np.array_equal(np.array(v.asked), np.array(whole.asked))


def test_last_resort_plans_deeper_before_giving_up():
    """A lone cube whose only grasp is the sixth GP would test: the capped plan (4 checks)
    misses it; the last resort goes on from the fifth and finds it, simulating nothing twice."""
    from mog_drake.planning.picking import LAST_RESORT_CHECKS, next_pick

    scene = make_scene([("small_yellow_cube", 0.02, -0.01, 0.3)])
    order = FakeVerifier()
    GraspPlanner(order, GraspConfig("gp", max_physics=10)).plan(scene, (0,))
    v = FakeVerifier(good=[order.asked[5]])
    capped = GraspPlanner(v, GraspConfig("gp", max_physics=4))
    d = next_pick(scene, capped)
    assert d.status == "grasp" and d.last_resort and np.allclose(d.grasp, order.asked[5])
    assert d.physics_checks == 6 and np.array_equal(np.array(v.asked), np.array(order.asked[:6]))
    v.asked.clear()
    assert (
        next_pick(scene, capped, PlannerSpec(loop=LoopConfig(last_resort=False))).status == "no_grasp"
        and len(v.asked) == 4
    )
    v = FakeVerifier()  # no grasp at all: the last resort spends its checks, then gives up
    d = next_pick(scene, GraspPlanner(v, GraspConfig("gp", max_physics=4)))
    assert d.status == "no_grasp" and not d.last_resort
    assert len(v.asked) == min(4 + LAST_RESORT_CHECKS, d.plans[0].candidates)


def test_the_last_resort_s_nominal_pass_checks_again_what_was_refused_as_not_robust():
    """A lone cube whose best candidates a robust check refuses for want of robustness (its
    screen, simulating nothing) while the nominal check alone lifts it with the first: the
    last resort's nominal pass takes that first candidate. Skipping every candidate the robust
    pass had tested, it began past them and the decision gave up with the cube on the table
    (two thin bars on their side were left so on the paper's cell). A candidate whose nominal
    check failed is not simulated again."""
    from mog_drake.planning.picking import next_pick

    scene = make_scene([("small_yellow_cube", 0.02, -0.01, 0.3)])
    order = FakeVerifier()
    GraspPlanner(order, GraspConfig("gp", max_physics=10)).plan(scene, (0,))

    class Robust:
        """Refuses every grasp: the first two as not robust, the next two in its nominal check."""

        def __init__(self):
            self.nominal = FakeVerifier(good=[order.asked[0]])
            self.asked = []

        def check(self, scene, group, grasp):
            self.asked.append(np.asarray(grasp).copy())
            if len(self.asked) <= 2:
                return GraspResult(False, error="not robust", complete=False, not_robust=True)
            return GraspResult(False)

    robust = Robust()
    d = next_pick(scene, GraspPlanner(robust, GraspConfig("gp", max_physics=4)))
    assert d.status == "grasp" and d.last_resort and not d.relaxed
    assert np.allclose(d.grasp, order.asked[0])
    assert d.plans[0].not_robust == d.plans[0].tested_indices[:2]
    assert len(robust.nominal.asked) == 1  # the first candidate, taken at once
    robust = Robust()
    robust.nominal.good = [order.asked[2]]  # lifts only where the robust pass's nominal check failed
    d = next_pick(scene, GraspPlanner(robust, GraspConfig("gp", max_physics=4)))
    assert not any(np.allclose(g, order.asked[2]) for g in robust.nominal.asked)


def test_the_last_resort_s_failures_are_remembered_while_the_group_lies_where_it_did():
    """A lone cube with no grasp: the last resort spends its checks and the decision keeps
    the verdict; the next decision on the same table replays both passes' verdicts (the capped
    plan's and the last resort's) with no physics, and plans again once the cube has moved."""
    from mog_drake.planning.picking import LAST_RESORT_CHECKS, next_pick

    scene = make_scene([("small_yellow_cube", 0.02, -0.01, 0.3)])
    v = FakeVerifier()
    planner = GraspPlanner(v, GraspConfig("gp", max_physics=4))
    d = next_pick(scene, planner, failures=())
    assert d.status == "no_grasp" and len(v.asked) == min(4 + LAST_RESORT_CHECKS, d.plans[0].candidates)
    assert [f.stage for f in d.failures] == ["", "nominal"]
    v.asked.clear()
    again = next_pick(scene, planner, failures=d.failures)
    assert again.status == "no_grasp" and v.asked == [] and again.remembered == 2
    assert [f.stage for f in again.failures] == ["", "nominal"]
    moved = make_scene([("small_yellow_cube", 0.03, -0.01, 0.3)])
    assert (
        next_pick(moved, planner, failures=d.failures).remembered == 0
        and len(v.asked) == len(d.plans[0].tested_indices) + d.plans[1].tested
    )


def test_a_large_group_gets_fewer_checks_and_the_last_resort_goes_past_them(scene):
    """max_physics_large caps the checks of a group of three objects, a pair keeps
    max_physics; before a decision gives up, the last resort goes on past the cap."""
    from mog_drake.planning.picking import next_pick

    trio, pair = tuple(scene.group), tuple(scene.group[:2])
    assert len(trio) == 3
    order = FakeVerifier()
    GraspPlanner(order, GraspConfig("gp", max_physics=10)).plan(scene, trio)
    cfg = GraspConfig("gp", max_physics=4, max_physics_large=2)
    assert GraspPlanner(FakeVerifier(), cfg).plan(scene, trio).tested == 2
    assert GraspPlanner(FakeVerifier(), cfg).plan(scene, pair).tested == 4
    v = FakeVerifier(good=[order.asked[4]])  # the trio's fifth candidate lifts it
    d = next_pick(scene, GraspPlanner(v, cfg))
    assert d.status == "grasp" and d.last_resort and d.group == trio
    assert d.plans[0].group == trio and d.plans[0].tested == 2


def test_sog_alone_takes_only_a_grasp_whose_check_lifts_the_object_alone():
    """Two bars side by side: the first two candidates of either bar lift both, the third only
    the bar planned for. Plain sog takes the first (two objects expected); with
    loop.sog_alone the check that lifts a neighbour is no success and the third is taken."""
    from mog_drake.planning.picking import next_pick

    scene = make_scene([("thin_bar", -0.012, 0.0, math.pi / 2), ("thin_bar", 0.0, 0.0, math.pi / 2)])

    class NeighbourAlongTwice(FakeVerifier):
        def check(self, scene, group, grasp):
            self.asked.append(tuple(group))
            both = len(self.asked) <= 2
            return GraspResult(True, lifted=[0, 1] if both else list(group))

    config = GraspConfig("gp", max_physics=4)
    v = NeighbourAlongTwice()
    d = next_pick(scene, GraspPlanner(v, config), PlannerSpec(mode="sog"), rng=np.random.default_rng(0))
    assert d.status == "grasp" and len(d.group) == 1 and d.expected == (0, 1) and d.physics_checks == 1

    v = NeighbourAlongTwice()
    spec = PlannerSpec(mode="sog", loop=LoopConfig(sog_alone=True))
    d = next_pick(scene, GraspPlanner(v, config), spec, rng=np.random.default_rng(0))
    assert d.status == "grasp" and d.expected == d.group and len(d.group) == 1 and d.physics_checks == 3
    np.testing.assert_allclose(d.grasp, d.plans[0].candidate_grasps[d.plans[0].tested_indices[2]])
    # mog is not touched by the setting: the pair lifted is its group.
    v = NeighbourAlongTwice()
    d = next_pick(scene, GraspPlanner(v, config), PlannerSpec(mode="mog", loop=LoopConfig(sog_alone=True)))
    assert d.status == "grasp" and d.expected == (0, 1) and d.physics_checks == 1


def test_a_partial_lift_is_taken_once_no_larger_group_is_left():
    """Three bars in a row: physics never lifts all three, but one candidate lifts two.
    With partial lifts that verified pair is the grasp (no pair or single is planned);
    without, Alg. 1 goes on to the singles."""
    from mog_drake.planning.picking import next_pick

    scene = make_scene(
        [
            ("thin_bar", -0.012, 0.0, math.pi / 2),
            ("thin_bar", 0.0, 0.0, math.pi / 2),
            ("thin_bar", 0.012, 0.0, math.pi / 2),
            ("small_yellow_cube", 0.15, 0.15, 0.0),
        ]
    )

    class LiftsTwoOnce(FakeVerifier):
        def check(self, scene, group, grasp):
            self.asked.append(tuple(group))
            if tuple(group) == (0, 1, 2) and len(self.asked) == 2:
                return GraspResult(False, lifted=[0, 1])  # the 2nd candidate lifts a pair
            if len(group) == 1:
                return GraspResult(True, lifted=list(group))
            return GraspResult(False)

    v = LiftsTwoOnce()
    d = next_pick(scene, GraspPlanner(v, GraspConfig("gp", max_physics=4)))
    assert d.status == "grasp" and d.partial and d.group == d.expected == (0, 1)
    assert set(v.asked) == {(0, 1, 2)} and d.groups_tried == 1
    np.testing.assert_allclose(d.grasp, d.plans[0].candidate_grasps[d.plans[0].tested_indices[1]])

    v = LiftsTwoOnce()
    d = next_pick(
        scene,
        GraspPlanner(v, GraspConfig("gp", max_physics=4)),
        PlannerSpec(loop=LoopConfig(partial_lifts=False)),
    )
    assert d.status == "grasp" and not d.partial and len(d.group) == 1


def test_an_incomplete_check_is_no_partial_lift():
    """A check stopped early saw objects in the air, not objects held: not a verified grasp."""
    from mog_drake.planning.picking import next_pick

    scene = make_scene([("thin_bar", -0.012, 0.0, math.pi / 2), ("thin_bar", 0.0, 0.0, math.pi / 2)])

    class StopsEarly(FakeVerifier):
        def check(self, scene, group, grasp):
            self.asked.append(tuple(group))
            return GraspResult(False, lifted=list(group), complete=False)

    d = next_pick(scene, GraspPlanner(StopsEarly(), GraspConfig("gp", max_physics=2)))
    assert d.status == "no_grasp" and not d.partial


def test_avoided_grasps_are_not_tried_again(scene):
    cands, ev = _figures(scene)
    v = FakeVerifier()
    first = GraspPlanner(v, GraspConfig("gp", max_physics=1)).plan(scene, scene.group)
    tried = first.candidate_grasps[first.tested_indices[0]]
    v2 = FakeVerifier()
    # The same grasp, turned by pi (the jaws are symmetric) and nudged 1 mm, is still avoided.
    avoid = [tried + [0.001, 0.0, math.pi]]
    again = GraspPlanner(v2, GraspConfig("gp", max_physics=1)).plan(scene, scene.group, avoid=avoid)
    assert again.tested == 1 and not np.allclose(v2.asked[0], tried)


def test_planner_system_does_not_repeat_its_last_grasp():
    from pydrake.common.value import AbstractValue
    from pydrake.systems.analysis import Simulator

    from mog_drake.config import LatencyConfig
    from mog_drake.systems.messages import Perceived
    from mog_drake.systems.planner import PlannerSystem

    scene = make_scene([("thin_bar", 0.0, 0.0, math.pi / 2), ("small_yellow_cube", 0.15, 0.15, 0.0)])

    class LiftsAnything(FakeVerifier):
        def check(self, scene, group, grasp):
            self.asked.append(np.asarray(grasp).copy())
            return GraspResult(True, lifted=list(group))

    # No latency: each decision is visible at the first update after its scene.
    system = PlannerSystem(
        GraspPlanner(LiftsAnything(), GraspConfig("gp")), latency=LatencyConfig("fixed", 0.0, 0.0)
    )
    ctx = system.CreateDefaultContext()
    port = system.GetInputPort("scene")
    port.FixValue(ctx, AbstractValue.Make(Perceived(1, scene)))
    sim = Simulator(system, ctx)
    sim.AdvanceTo(0.015)
    first = system.GetOutputPort("decision").Eval(ctx)
    port.FixValue(ctx, AbstractValue.Make(Perceived(2, scene)))  # the world did not change
    sim.AdvanceTo(0.045)  # planned in the update after the scene, visible in the next
    second = system.GetOutputPort("decision").Eval(ctx)
    assert first.counter == 1 and second.counter == 2 and len(second.recent) == 2
    assert not np.allclose(first.decision.grasp, second.decision.grasp)


def test_squeeze_margin_keeps_a_lone_thin_bar_out_of_end_grips():
    from mog_drake.geometry.polygon import squeeze_basins

    scene = make_scene([("thin_bar", 0.0, 0.0, 0.3)], group=[0])
    axis = 0.3
    for margin, end_grips in ((0.0, True), (12.0, False)):
        v = FakeVerifier()
        cfg = GraspConfig(edge_orientations=True, min_squeeze_margin_deg=margin)
        res = GraspPlanner(v, cfg).plan(scene, [0])
        off_axis = np.abs(np.remainder(res.candidate_grasps[:, 2] - axis + np.pi / 2, np.pi) - np.pi / 2)
        assert bool(np.any(off_axis < math.atan(7 / 50))) == end_grips
        assert res.tested == len(v.asked) > 0
        _, m = squeeze_basins(scene.polygon(0), res.candidate_grasps[:, 2])
        assert (m.min() >= math.radians(margin)) if margin else (m.min() < math.radians(12))
    with pytest.raises(MogError, match="min_squeeze_margin_deg"):
        GraspConfig(min_squeeze_margin_deg=95.0)
    # groups of two or more are not filtered
    pair = make_scene([("thin_bar", 0.0, 0.0, 0.3), ("thin_bar", 0.0, 0.012, 0.3)], group=[0, 1])
    cands_pair = GraspPlanner(FakeVerifier(), GraspConfig(min_squeeze_margin_deg=12.0)).plan(pair, [0, 1])
    assert len(cands_pair.candidate_grasps) == len(gen_grasp_cands(pair.polygons(), [0, 1]))


def test_vary_axis_tries_a_new_closing_axis_after_each_failure():
    # A bar lying on its side (50 x 30 mm): the area ranking puts several end-to-end grips first.
    scene = make_scene([("thin_bar:on_side", 0.0, 0.0, 0.5)], group=[0])
    gaps = {}
    for vary in (False, True):
        v = FakeVerifier()  # every check fails
        res = GraspPlanner(v, GraspConfig(edge_orientations=True, max_physics=4, vary_axis=vary)).plan(
            scene, [0]
        )
        assert res.grasp is None and res.tested == 4
        axes = np.array([g[2] for g in v.asked])
        gaps[vary] = axis_gap(axes[:, None], axes[None, :])[np.triu_indices(4, 1)]
    assert gaps[False].min() < GraspPlanner.AXIS_TOL  # the plain ranking repeats an axis
    assert gaps[True].min() >= GraspPlanner.AXIS_TOL  # each retry is on a new axis


def test_lone_widest_basin_grips_a_bar_on_its_side_across_at_its_centre():
    yaw = 0.5
    scene = make_scene([("thin_bar:on_side", 0.02, -0.01, yaw)], group=[0])
    first = {}
    for widest in (False, True):
        v = FakeVerifier()
        cfg = GraspConfig(edge_orientations=True, max_physics=1, lone_widest_basin=widest)
        GraspPlanner(v, cfg).plan(scene, [0])
        first[widest] = v.asked[0]
    assert axis_gap(first[False][2], yaw) < math.radians(10)  # area alone: end to end
    assert axis_gap(first[True][2], yaw + np.pi / 2) < 1e-9  # widest basin: across, on the edge normal
    assert np.linalg.norm(first[True][:2] - [0.02, -0.01]) < 0.002
    # groups of two or more keep the paper's ranking
    pair = make_scene([("thin_bar", 0.0, 0.0, 0.3), ("thin_bar", 0.0, 0.012, 0.3)], group=[0, 1])
    asked = []
    for widest in (False, True):
        v = FakeVerifier()
        GraspPlanner(v, GraspConfig(max_physics=3, lone_widest_basin=widest)).plan(pair, [0, 1])
        asked.append(np.array(v.asked))
    np.testing.assert_array_equal(asked[0], asked[1])


def test_a_failed_group_is_not_planned_again_while_its_surroundings_are_unchanged():
    """Picking the lone cube leaves the bar row (no grasp found) where it was: the next
    decision replays the row's failure, partial lift included, in the new scene's object ids,
    without a physics check. A bar moved 5 mm, or a new object within reach, and it is
    planned again."""
    from mog_drake.planning.picking import next_pick

    bars = [("thin_bar", -0.012, 0.0, math.pi / 2), ("thin_bar", 0.0, 0.0, math.pi / 2)]
    bars.append(("thin_bar", 0.012, 0.0, math.pi / 2))

    class PairAtBest(FakeVerifier):  # the row: every check lifts its first two bars, never all
        def check(self, scene, group, grasp):
            self.asked.append(tuple(group))
            if len(group) == 1:
                return GraspResult(True, lifted=list(group))
            return GraspResult(False, lifted=sorted(group)[:2])

    v = PairAtBest()
    planner = GraspPlanner(v, GraspConfig("gp", max_physics=2))
    d1 = next_pick(make_scene(bars + [("small_yellow_cube", 0.15, 0.15, 0.0)]), planner, failures=())
    assert d1.status == "grasp" and d1.partial and d1.expected == (0, 1) and d1.remembered == 0
    assert [f.group for f in d1.failures] == [(0, 1, 2)] and len(v.asked) == 2

    # The pair was lifted away... in a world that did not listen: the row is still there, its
    # objects listed in another order (ids 2, 1, 0 now), the cube gone.
    v.asked.clear()
    d2 = next_pick(make_scene(bars[::-1]), planner, failures=d1.failures)
    assert v.asked == [] and d2.remembered == 1 and d2.physics_checks == 0
    assert d2.status == "grasp" and d2.partial and set(d2.expected) == {2, 1}
    np.testing.assert_allclose(d2.grasp, d1.grasp)
    assert [f.group for f in d2.failures] == [(0, 1, 2)]
    # The robot tried that pair grasp and the row is still there: it is not offered again,
    # the singles are planned instead.
    d2b = next_pick(make_scene(bars[::-1]), planner, avoid=[d1.grasp], failures=d1.failures)
    assert d2b.remembered == 1 and d2b.status == "grasp" and not d2b.partial
    assert v.asked == [d2b.group] and len(d2b.group) == 1
    v.asked.clear()

    moved = [bars[0], bars[1], ("thin_bar", 0.017, 0.0, math.pi / 2)]
    d3 = next_pick(make_scene(moved), planner, failures=d1.failures)
    assert d3.remembered == 0 and v.asked == [(0, 1, 2)] * 2

    v.asked.clear()
    crowded = make_scene(bars + [("small_yellow_cube", 0.0, 0.06, 0.0)])
    d4 = next_pick(crowded, planner, failures=d1.failures)
    assert d4.remembered == 0 and v.asked[:2] == [(0, 1, 2)] * 2

    # Several failures remembered: the one that matches is replayed, the others kept.
    elsewhere = [(name, x + 0.2, y + 0.1, th) for name, x, y, th in bars]  # also ids (0, 1, 2)
    other = next_pick(make_scene(elsewhere), planner, failures=())
    assert [f.group for f in other.failures] == [(0, 1, 2)]
    v.asked.clear()
    d6 = next_pick(make_scene(bars[::-1]), planner, failures=other.failures + d1.failures)
    assert v.asked == [] and d6.remembered == 1 and len(d6.failures) == 2
    assert d6.failures[1] is other.failures[0]

    # Off (failures=None), as in the paper's Alg. 1: nothing remembered.
    v.asked.clear()
    d5 = next_pick(make_scene(bars[::-1]), planner)
    assert d5.failures == () and d5.remembered == 0 and len(v.asked) == 2


def test_the_lookahead_plans_the_next_grasp_before_its_image_and_it_is_replayed_if_nothing_moved():
    """A decision grasps the cube; the lookahead plans the table without it and finds the
    hexagon's grasp. In the next image (the cube gone, ids in another order) that grasp is
    taken with no physics check. Had the grasp pushed the hexagon 5 mm, it is planned again;
    so it is if its jaws would land where a missed grasp's came down."""
    from dataclasses import replace

    from mog_drake.planning.config import PlannerSpec
    from mog_drake.planning.lookahead import lookahead
    from mog_drake.planning.picking import next_pick

    cube = ("small_yellow_cube", 0.0, 0.0, 0.0)
    hexagon = ("large_hexagon", 0.15, 0.1, 0.3)

    class LiftsAnything(FakeVerifier):
        def check(self, scene, group, grasp):
            self.asked.append(np.asarray(grasp).copy())
            return GraspResult(True, lifted=list(group))

    v = LiftsAnything()
    planner = GraspPlanner(v, PlannerSpec().grasp)
    spec = PlannerSpec(mode="mog")
    first = make_scene([cube, hexagon])
    d1 = next_pick(first, planner, spec, failures=())
    assert d1.status == "grasp" and d1.group in ((0,), (1,))
    grasped, other = d1.group[0], 1 - d1.group[0]
    memory = lookahead(first, d1, planner, spec)
    assert memory and memory[0].result.found and len(v.asked) == 2  # one check now, one ahead

    v.asked.clear()
    left = replace(first, objects=[first.objects[other]])
    d2 = next_pick(left, planner, spec, failures=memory)
    assert v.asked == [] and d2.physics_checks == 0 and d2.remembered == 1
    assert d2.status == "grasp" and d2.group == (0,)
    np.testing.assert_allclose(d2.grasp, memory[0].result.grasp)

    o = first.objects[other]
    moved = replace(first, objects=[replace(o, x=o.x + 0.005)])
    d3 = next_pick(moved, planner, spec, failures=memory)
    assert len(v.asked) == 1 and d3.remembered == 0 and d3.status == "grasp"
    assert first.objects[grasped] != o

    # Nothing moved, but a grasp that took nothing since put its jaws where the remembered
    # grasp's would go (`jaw_obstacles`): planned again, off them.
    from mog_drake.geometry import jaw_collision_free
    from mog_drake.planning.planner import jaw_footprints, jaw_obstacles

    v.asked.clear()
    kept_off = replace(left, meta={"missed_jaws": jaw_footprints(memory[0].result.grasp)})
    d4 = next_pick(kept_off, planner, spec, failures=memory)
    assert len(v.asked) == 1 and d4.remembered == 0 and d4.status == "grasp"
    assert jaw_collision_free(jaw_obstacles(kept_off), d4.grasp)[0]


def test_in_sog_the_object_the_lookahead_drew_is_tried_first_and_its_grasp_replayed():
    """Single-object picking draws objects in a random order until one has a grasp. Its
    lookahead draws on the table without the grasped object; in the next image (ids in another
    order, the decision's own draw another) the object it found a grasp for is tried first and
    taken with no physics check. Moved 5 mm, that object is no longer the one drawn."""
    from dataclasses import replace

    from mog_drake.planning.config import PlannerSpec
    from mog_drake.planning.lookahead import lookahead
    from mog_drake.planning.picking import next_pick

    shapes = [
        ("small_yellow_cube", 0.0, 0.0, 0.0),
        ("large_hexagon", 0.15, 0.1, 0.3),
        ("blue_pentagon", -0.12, 0.12, 0.2),
        ("thick_bar", 0.1, -0.15, 1.0),
    ]

    class LiftsAnything(FakeVerifier):
        def check(self, scene, group, grasp):
            self.asked.append(tuple(group))
            return GraspResult(True, lifted=list(group))

    v = LiftsAnything()
    planner = GraspPlanner(v, PlannerSpec().grasp)
    spec = PlannerSpec(mode="sog")
    first = make_scene(shapes)
    d1 = next_pick(first, planner, spec, np.random.default_rng(0), failures=())
    memory = lookahead(first, d1, planner, spec, np.random.default_rng(1))
    rest = [o for i, o in enumerate(first.objects) if i != d1.group[0]]
    assert memory[0].result.found
    drawn = rest[memory[0].group[0]]

    left = rest[::-1]
    for seed in range(6):  # whatever the decision's own draw
        v.asked.clear()
        d2 = next_pick(
            replace(first, objects=left), planner, spec, np.random.default_rng(seed), failures=memory
        )
        assert v.asked == [] and d2.physics_checks == 0 and d2.remembered == 1
        assert left[d2.group[0]] == drawn

    moved = [replace(o, x=o.x + 0.005) if o == drawn else o for o in left]
    firsts = set()
    for seed in range(6):
        v.asked.clear()
        d3 = next_pick(
            replace(first, objects=moved), planner, spec, np.random.default_rng(seed), failures=memory
        )
        assert d3.remembered == 0 and len(v.asked) == 1
        firsts.add(moved[d3.group[0]].shape)
    assert len(firsts) > 1  # the decision's own random order again


def test_clear_of_boxes_agrees_with_shapely_on_the_open_gripper_footprint():
    """The separating-axis test against the exact overlap of the gripper's footprint (both
    jaws and S between them) with a box, on random grasps around it, touching excepted."""
    from shapely.geometry import Polygon, box

    from mog_drake.geometry import GripperGeometry
    from mog_drake.geometry.gripper import clear_of_boxes

    g = GripperGeometry()
    r = np.random.default_rng(7)
    grasps = np.column_stack(
        [r.uniform(-0.15, 0.15, 400), r.uniform(-0.15, 0.15, 400), r.uniform(0, np.pi, 400)]
    )
    b = (-0.04, 0.06, -0.02, 0.03)
    clear = clear_of_boxes(grasps, [b], g)
    for u, ok in zip(grasps, clear, strict=True):
        rect = g.rectangles(u)
        foot = Polygon(rect["left_jaw"]).union(Polygon(rect["S"])).union(Polygon(rect["right_jaw"]))
        assert ok == (foot.intersection(box(b[0], b[2], b[1], b[3])).area < 1e-12)
    assert 50 < clear.sum() < 350  # both verdicts occur


def test_the_planners_jaws_stay_out_of_the_bin():
    """A thin bar lying on its side against the bin's wall: the grasp the planner ranks first
    closes across its 30 mm width, with one jaw on the wall. With the scenario's keep-out
    (make_planner) no candidate's jaws enter the bin, and the bar is held end to end or not
    at all; an object in the open is planned as before."""
    from mog_drake.geometry.gripper import clear_of_boxes
    from mog_drake.scenario import Scenario

    sc = Scenario()
    (box,) = sc.keep_out()
    bar = make_scene([("thin_bar:on_side", -0.215, box[2] - 0.012, 0.0)], table=(-0.3, 0.3, -0.4, 0.4))
    cfg = sc.planner.grasp
    free, kept = FakeVerifier(), FakeVerifier()
    GraspPlanner(free, cfg).plan(bar, (0,))
    GraspPlanner(kept, cfg, keep_out=sc.keep_out()).plan(bar, (0,))
    assert not clear_of_boxes(free.asked[0], [box])[0]  # the first choice: a jaw on the wall
    assert kept.asked and clear_of_boxes(np.array(kept.asked), [box]).all()
    away = make_scene([("thin_bar:on_side", -0.215, 0.0, 0.0)], table=(-0.3, 0.3, -0.4, 0.4))
    a, b = FakeVerifier(), FakeVerifier()
    GraspPlanner(a, cfg).plan(away, (0,))
    GraspPlanner(b, cfg, keep_out=sc.keep_out()).plan(away, (0,))
    assert np.array_equal(np.array(a.asked), np.array(b.asked))
    with pytest.raises(MogError, match="keep-out"):
        GraspPlanner(FakeVerifier(), keep_out=[(0.1, 0.0, 0.0, 0.1)])


def test_the_planners_jaws_stay_off_what_perception_saw_but_could_not_fit():
    """An unrecognised blob (a knocked-over or leaning prism perception reported by its
    outline, ``meta["unrecognised"]``) where the first-ranked grasp of a bar puts a jaw: no
    grasp the planner then asks about puts a jaw on it; without the blob the same grasp is
    asked first."""
    from mog_drake.geometry import GripperGeometry, jaw_collision_free
    from mog_drake.planning.planner import jaw_obstacles

    bar = make_scene([("thick_bar", 0.0, 0.0, 0.3)], group=[0])
    first = FakeVerifier()
    GraspPlanner(first, GraspConfig()).plan(bar, [0])
    x, y, th = first.asked[0]
    g = GripperGeometry()
    at = g.w_g / 2 + g.plate_thickness / 2  # the right jaw's centre, on the closing axis
    cx, cy = x + at * np.cos(th), y + at * np.sin(th)
    square = [[cx - 0.01, cy - 0.01], [cx + 0.01, cy - 0.01], [cx + 0.01, cy + 0.01], [cx - 0.01, cy + 0.01]]
    bar.meta["unrecognised"] = [{"vertices": square, "top": 0.02}]
    blobs = jaw_obstacles(bar)
    assert not jaw_collision_free(blobs, first.asked[0])[0]
    seen = FakeVerifier()
    GraspPlanner(seen, GraspConfig()).plan(bar, [0])
    assert seen.asked and jaw_collision_free(blobs, np.array(seen.asked)).all()
    assert jaw_obstacles(make_scene([("thick_bar", 0.0, 0.0, 0.0)])) is None


def test_failed_grasps_are_tallied_per_object_across_images():
    """tally_misses: a grasp that took none of its targets counts one miss for each; the count
    follows its object to where the failed grasp nudged it (ids differ between images), is
    not given to a neighbour of another shape, and is dropped once the object is gone. At
    MAX_MISSES the object's id in the new image is returned."""
    from mog_drake.planning.picking import MAX_MISSES, MISS_RADIUS, tally_misses

    hexagon = ("large_hexagon", 0.05, -0.10, 0.0)
    quad = ("blue_quad", 0.07, -0.10, 0.0)  # 2 cm away: within MISS_RADIUS, another shape
    misses, out = tally_misses((), (("large_hexagon", 0.05, -0.10),), make_scene([quad, hexagon]))
    assert misses == (("large_hexagon", 0.05, -0.10, 1),) and out == []
    # Nudged 1 cm and listed first now: the same object, its count carried.
    nudged = make_scene([("large_hexagon", 0.06, -0.10, 0.4), quad])
    for _ in range(2, MAX_MISSES + 1):
        misses, out = tally_misses(misses, (("large_hexagon", *misses[0][1:3]),), nudged)
    assert misses == (("large_hexagon", 0.06, -0.10, MAX_MISSES),) and out == [0]
    # A grasp of the quad that took it: nothing new for the hexagon, its count stands.
    assert tally_misses(misses, (("blue_quad", 0.07, -0.10),), make_scene([hexagon]))[0][0][3] == MAX_MISSES
    # A grasp of two that took one of them: no miss for the other.
    both = (("large_hexagon", 0.05, -0.10), ("blue_quad", 0.07, -0.10))
    assert tally_misses((), both, make_scene([hexagon])) == ((), [])
    # Moved farther than MISS_RADIUS (or taken): forgotten.
    far = make_scene([("large_hexagon", 0.05 + 1.5 * MISS_RADIUS, -0.10, 0.0)])
    assert tally_misses(misses, (), far) == ((), [])


def test_the_object_nearest_each_jaw_of_a_missed_grasp_is_suspected_until_it_is_taken():
    """tally_suspects: for each jaw of a grasp that took nothing, the nearest object (not a
    target) within SUSPECT_NEAR becomes a suspect, its margin its gap plus SUSPECT_EXTRA; one
    farther is not; a suspect follows its object between images and is dropped once gone, and
    only then.
    jaw_obstacles keeps the jaws its margin off it, except in a grasp of the suspect itself."""
    import shapely

    from mog_drake.geometry import jaw_collision_free
    from mog_drake.planning.picking import SUSPECT_EXTRA, SUSPECT_NEAR, tally_suspects, wary_outlines
    from mog_drake.planning.planner import jaw_footprints, jaw_obstacles

    grasp = (0.0, 0.0, 0.0)  # closing along x: the jaws stand at x = +-(w_g/2 .. w_g/2 + plate)
    right, left = (shapely.Polygon(f) for f in jaw_footprints(grasp)[::-1])
    assert right.centroid.x > 0 > left.centroid.x
    cube = shapely.Polygon(make_scene([("small_yellow_cube", 0.0, 0.0, 0.0)]).polygon(0))
    half = cube.bounds[2]
    near_x = right.bounds[2] + 0.003 + half  # 3 mm beyond the right jaw's outer face
    far_x = left.bounds[0] - (SUSPECT_NEAR + 0.002) - half  # 10 mm beyond the left jaw
    objects = [("thick_bar", 0.0, 0.0, np.pi / 2), ("small_yellow_cube", near_x, 0.0, 0.0)]
    objects.append(("small_yellow_cube", far_x, 0.0, 0.0))
    scene = make_scene(objects)
    target = (("thick_bar", 0.0, 0.0),)
    suspects = tally_suspects((), scene, jaw_footprints(grasp), target)
    assert [s[:3] for s in suspects] == [("small_yellow_cube", near_x, 0.0)]
    assert suspects[0][3] == pytest.approx(0.003 + SUSPECT_EXTRA, abs=1e-4)
    # No miss since: it stays, following its object (listed first now, nudged 2 mm).
    moved = make_scene([("small_yellow_cube", near_x + 0.002, 0.0, 0.0), *objects[:1]])
    assert tally_suspects(suspects, moved) == (("small_yellow_cube", near_x + 0.002, 0.0, suspects[0][3]),)
    # Taken: forgotten.
    assert tally_suspects(suspects, make_scene(objects[:1])) == ()
    # However many misses came since: ten suspects from earlier ones, and the new one.
    earlier = tuple(("small_yellow_cube", 0.1 * k, 0.2, 0.004) for k in range(10))
    crowd = make_scene(objects + [s[:3] + (0.0,) for s in earlier])
    assert tally_suspects(earlier, crowd, jaw_footprints(grasp), target) == earlier + suspects
    # The jaws stay its margin off it, unless the grasp is of the suspect itself.
    scene.meta["wary"] = wary_outlines(suspects, scene)
    grown = shapely.Polygon(scene.meta["wary"][0]["vertices"])
    assert shapely.Polygon(scene.polygon(1)).buffer(suspects[0][3] - 1e-6).within(grown)
    blobs = jaw_obstacles(scene, (0,))
    assert not jaw_collision_free(blobs, (-0.0015, 0.0, 0.0))[0]  # its right jaw 4.5 mm from the cube
    assert jaw_collision_free(blobs, (-0.0025, 0.0, 0.0))[0]  # 5.5 mm
    assert jaw_obstacles(scene, (1,)) is None


def test_objects_given_up_on_are_not_planned_and_alone_they_end_the_run():
    from mog_drake.planning.picking import next_pick

    scene = make_scene([("large_hexagon", 0.05, -0.10, 0.0), ("blue_quad", -0.10, 0.10, 0.0)])
    lifts = FakeVerifier()
    lifts.check = lambda s, group, grasp: GraspResult(True, lifted=list(group))
    for mode in ("mog", "sog"):
        spec = PlannerSpec(mode=mode)
        d = next_pick(scene, GraspPlanner(lifts), spec, np.random.default_rng(0), exclude=[0])
        assert d.status == "grasp" and d.group == (1,)
        d = next_pick(scene, GraspPlanner(lifts), spec, np.random.default_rng(0), exclude=[0, 1])
        assert d.status == "gave_up" and d.grasp is None
