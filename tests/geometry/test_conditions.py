import math

import numpy as np
import pytest
import shapely
from conftest import make_scene
from hypothesis import given, settings
from hypothesis import strategies as st

from mog_drake.errors import MogError
from mog_drake.geometry import (
    GripperGeometry,
    candidate_grasps,
    evaluate_grasps,
    gen_grasp_cands,
    grasp_failure,
    jaw_collision_free,
    rank_grasp_cands,
)
from mog_drake.geometry.clip import box_intersection_area
from mog_drake.scenes import row_scene

G = GripperGeometry()


def test_gripper_defaults_are_the_papers():
    assert G.w_g == pytest.approx(0.075)
    assert G.s_size == pytest.approx((0.075, 0.020))


def test_two_bars_centred_hand_computed():
    # Two thin bars (7 mm across x, 50 mm along y) at x = -10 mm and +10 mm; grasp at the
    # origin along x. S spans x in [-37.5, 37.5] mm, y in [-10, 10] mm.
    scene = make_scene(
        [("thin_bar", -0.010, 0.0, math.pi / 2), ("thin_bar", 0.010, 0.0, math.pi / 2)], group=(0, 1)
    )
    ev = evaluate_grasps(scene.polygons(), (0, 1), [[0.0, 0.0, 0.0]])
    assert ev.b_l[0] == pytest.approx(0.0375 - 0.0135)
    assert ev.b_r[0] == pytest.approx(0.0375 - 0.0135)
    assert ev.h0[0] == pytest.approx(0.027)  # from -13.5 to +13.5 mm
    assert ev.h_fmin == pytest.approx(0.014)
    np.testing.assert_allclose(ev.areas[0], [0.007 * 0.020] * 2)
    assert ev.diameter_ok[0] and ev.area_ok[0] and ev.collision_free[0]


def test_diameter_condition_violated():
    # Two 29 mm cubes side by side along x, grasped with the closing axis along y: the jaws
    # can only squeeze them to 29 mm, but they need h_fmin = 58 mm in series.
    scene = make_scene([("dark_yellow_cube", -0.0152, 0.0, 0.0), ("dark_yellow_cube", 0.0152, 0.0, 0.0)])
    # Grasp at 90 deg: the closing axis is y, the cubes sit side by side across it.
    ev = evaluate_grasps(scene.polygons(), (0, 1), [[0.0, 0.0, math.pi / 2]])
    assert ev.h0[0] == pytest.approx(0.029)  # one cube's extent along y
    assert ev.h_fmin == pytest.approx(0.058)
    assert not ev.diameter_ok[0]
    assert grasp_failure(ev)[0]


def test_area_condition_violated_by_object_outside_s():
    scene = make_scene([("small_yellow_cube", 0.0, 0.0, 0.0), ("small_yellow_cube", 0.0, 0.040, 0.0)])
    ev = evaluate_grasps(scene.polygons(), (0, 1), [[0.0, 0.0, 0.0]])
    assert ev.areas[0, 0] == pytest.approx(0.025 * 0.020)
    assert ev.areas[0, 1] == 0.0
    assert not ev.area_ok[0] and grasp_failure(ev)[0]


def test_jaw_collision_detected_and_touching_allowed():
    # Cube edge at x = 37.5 + 5 mm sits inside the right jaw (37.5..47.5 mm).
    scene = make_scene([("small_yellow_cube", 0.030, 0.0, 0.0)])
    assert not jaw_collision_free(scene.polygons(), [[0.0, 0.0, 0.0]])[0]
    # Cube centred: fully inside S, no collision.
    scene = make_scene([("small_yellow_cube", 0.0, 0.0, 0.0)])
    assert jaw_collision_free(scene.polygons(), [[0.0, 0.0, 0.0]])[0]
    # Cube whose right edge exactly touches the left jaw's outer face at x = -47.5 mm.
    scene = make_scene([("small_yellow_cube", -0.0475 - 0.0125, 0.0, 0.0)])
    assert jaw_collision_free(scene.polygons(), [[0.0, 0.0, 0.0]])[0]


def test_non_group_object_in_s_bounds_h0_but_not_h_fmin():
    scene = make_scene([("thin_bar", 0.0, 0.0, math.pi / 2), ("thin_bar", -0.030, 0.0, math.pi / 2)])
    ev = evaluate_grasps(scene.polygons(), (0,), [[0.0, 0.0, 0.0]])
    assert ev.h_fmin == pytest.approx(0.007)
    assert ev.h0[0] == pytest.approx(0.0035 + 0.0335)  # from the other bar's left face to ours
    assert ev.record(0)["other_objects_in_S"] == [1]


def _shapely_truth(scene, group, grasp):
    rects = G.rectangles(grasp)
    S, L, R = (shapely.Polygon(rects[k]) for k in ("S", "left_jaw", "right_jaw"))
    polys = scene.shapely_polygons()
    collide = any(
        shapely.intersection(p, L).area > 1e-10 or shapely.intersection(p, R).area > 1e-10 for p in polys
    )
    areas = [shapely.intersection(polys[g], S).area for g in group]
    # h0: extent along the closing axis of all material inside S, in the grasp frame.
    c, s = math.cos(grasp[2]), math.sin(grasp[2])
    xs = []
    for p in polys:
        inter = shapely.intersection(p, S)
        if inter.area > 1e-10:
            pts = np.asarray(inter.exterior.coords) - grasp[:2]
            xs.extend(pts @ np.array([c, s]))
    h0 = (max(xs) - min(xs)) if xs else 0.0
    return collide, np.array(areas), h0


@pytest.mark.parametrize("n_class", [2, 3, 4, 5, 6, 7])
def test_vectorized_figures_match_shapely(n_class):
    scene = row_scene(n_class, np.random.default_rng(n_class))
    polys = scene.polygons()
    grasps = candidate_grasps(polys, scene.group)
    ev = evaluate_grasps(polys, scene.group, grasps)
    for i in range(0, len(grasps), 3):
        collide, areas, h0 = _shapely_truth(scene, scene.group, grasps[i])
        assert ev.collision_free[i] == (not collide)
        np.testing.assert_allclose(ev.areas[i], areas, atol=1e-9)
        assert ev.h0[i] == pytest.approx(h0, abs=1e-7)


@settings(max_examples=80, deadline=None)
@given(
    st.sampled_from(["thin_bar", "red_triangle", "large_hexagon", "blue_pentagon", "yellow_quad"]),
    st.floats(-0.06, 0.06),
    st.floats(-0.03, 0.03),
    st.floats(-4, 4),
    st.floats(-0.05, 0.05),
    st.floats(-0.02, 0.02),
)
def test_box_area_matches_shapely(shape, x, y, th, bx, by):
    from mog_drake.geometry.polygon import transform
    from mog_drake.scenes import default_library

    poly = transform(default_library()[shape].vertices, x, y, th)
    box = (bx - 0.0375, bx + 0.0375, by - 0.01, by + 0.01)
    got = box_intersection_area(poly[None], box)[0]
    want = shapely.intersection(shapely.Polygon(poly), shapely.box(box[0], box[2], box[1], box[3])).area
    assert got == pytest.approx(want, abs=1e-12)


def test_box_area_shared_edges_count_once():
    sq = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]])
    assert box_intersection_area(sq, (0.0, 1.0, 0.0, 1.0))[0] == pytest.approx(1.0)  # identical
    assert box_intersection_area(sq, (0.0, 2.0, 0.0, 1.0))[0] == pytest.approx(1.0)  # three shared edges
    assert box_intersection_area(sq, (1.0, 2.0, 0.0, 1.0))[0] == pytest.approx(0.0)  # touching outside
    assert box_intersection_area(sq, (0.5, 2.0, -1.0, 0.5))[0] == pytest.approx(0.25)


@settings(max_examples=40, deadline=None)
@given(
    st.integers(2, 7), st.integers(0, 10_000), st.floats(-0.5, 0.5), st.floats(-0.5, 0.5), st.floats(-7, 7)
)
def test_every_figure_is_invariant_under_a_rigid_motion(n_class, seed, dx, dy, dth):
    """Moving scene and grasps together by one rigid motion changes no figure or verdict."""
    from mog_drake.scenes import Scene, SceneObject

    scene = row_scene(n_class, np.random.default_rng(seed))
    c, s = math.cos(dth), math.sin(dth)

    def move(x, y, th):
        return c * x - s * y + dx, s * x + c * y + dy, th + dth

    moved = Scene(
        [SceneObject(o.shape, *move(*o.pose)) for o in scene.objects],
        scene.library,
        table=(-10, 10, -10, 10),
        group=scene.group,
    )
    polys, polys_m = scene.polygons(), moved.polygons()
    grasps = candidate_grasps(polys, scene.group)[::5]
    grasps_m = np.array([move(*g) for g in grasps])
    a = evaluate_grasps(polys, scene.group, grasps)
    b = evaluate_grasps(polys_m, scene.group, grasps_m)
    np.testing.assert_allclose(a.h0, b.h0, atol=1e-9)
    np.testing.assert_allclose(a.areas, b.areas, atol=1e-10)
    # Verdicts may only differ where a figure sits within round-off of its threshold.
    robust = (np.abs(a.h0 - a.h_fmin) > 1e-8) & (np.abs(a.areas).min(axis=1) > 1e-8)
    np.testing.assert_array_equal(a.diameter_ok[robust], b.diameter_ok[robust])
    np.testing.assert_array_equal(a.area_ok[robust], b.area_ok[robust])


def test_candidates_cover_the_hull_and_rank_by_total_area():
    scene = row_scene(3, np.random.default_rng(3))
    polys = scene.polygons()
    grasps = candidate_grasps(polys, scene.group, n_positions=70, n_orientations=7)
    n_pos = len(grasps) // 7
    assert 50 <= n_pos <= 70
    np.testing.assert_allclose(np.unique(grasps[:, 2]), np.arange(7) * np.pi / 7)
    hull = shapely.convex_hull(shapely.union_all(scene.shapely_polygons()))
    assert all(hull.contains(shapely.Point(g[:2])) for g in grasps)
    free = gen_grasp_cands(polys, scene.group)
    assert jaw_collision_free(polys, free).all()
    ev = evaluate_grasps(polys, scene.group, free)
    order = rank_grasp_cands(ev)
    assert np.all(np.diff(ev.area_total[order]) <= 0)


def test_edge_orientations_come_first_and_meet_a_lone_bar_flat():
    from conftest import make_scene

    from mog_drake.geometry.candidates import edge_normal_angles

    yaw = 0.3  # no multiple of pi / 7
    scene = make_scene([("thin_bar", 0.0, 0.0, yaw)], group=[0])
    polys = scene.polygons()
    across, along = np.remainder(yaw + np.pi / 2, np.pi), yaw
    # the long sides (50 mm) outweigh the ends (7 mm)
    np.testing.assert_allclose(edge_normal_angles(polys, [0]), [across, along], atol=1e-9)
    grid = candidate_grasps(polys, [0], 20, 7)
    np.testing.assert_allclose(np.unique(grid[:, 2]), np.arange(7) * np.pi / 7)
    ext = candidate_grasps(polys, [0], 20, 7, edge_orientations=True)
    n_pos = len(grid) // 7
    assert len(ext) == n_pos * 9
    np.testing.assert_allclose(ext[: n_pos * 2, 2], np.tile([across, along], n_pos))
    np.testing.assert_allclose(ext[n_pos * 2 :], grid)
    # Closing along the bar keeps all of it inside S (75 x 20 mm), so that axis ranks first;
    # the grid's nearest angle (pi / 7) keeps all of it too, and the tie goes to the edge.
    for edges, want in ((False, np.pi / 7), (True, along)):
        free = gen_grasp_cands(polys, [0], None, 20, 7, edge_orientations=edges)
        ev = evaluate_grasps(polys, [0], free)
        order = rank_grasp_cands(ev)
        assert ev.area_total[order[0]] == pytest.approx(scene.shape(0).area)
        assert free[order[0], 2] == pytest.approx(want)
    # a grid angle that repeats an edge direction is left out
    square = make_scene([("thin_bar", 0.0, 0.0, 0.0)], group=[0])
    ext0 = candidate_grasps(square.polygons(), [0], 20, 7, edge_orientations=True)
    assert len(ext0) == n_pos * 8 and np.sum(np.isclose(ext0[:, 2], 0.0)) == n_pos


def test_squeeze_basins_of_a_bar_and_a_square():
    from conftest import make_scene

    from mog_drake.geometry.polygon import squeeze_basins

    yaw = 0.3
    bar = make_scene([("thin_bar", 0.0, 0.0, yaw)]).polygon(0)
    along, across = yaw, yaw + np.pi / 2
    final, margin = squeeze_basins(bar, [along, along + 0.1, along - 0.1, along + 0.2, across, across + 1.0])
    # within atan(7/50) of the bar's axis the squeeze ends end to end; beyond, across
    np.testing.assert_allclose(final, [along, along, along, across, across, across], atol=np.pi / 1440)
    edge = math.degrees(math.atan(7 / 50))
    np.testing.assert_allclose(np.degrees(margin), [edge] * 3 + [90 - edge] * 3, atol=0.2)
    cube = make_scene([("small_yellow_cube", 0.0, 0.0, 0.0)]).polygon(0)
    _, m = squeeze_basins(cube, np.linspace(0, np.pi, 13))
    np.testing.assert_allclose(np.degrees(m), 45.0, atol=0.2)


def test_frictional_columns_admit_objects_side_by_side_across_the_jaws():
    """Two 25 mm cubes side by side across the plates (2 mm apart in y): h0 = 25 mm, the
    paper's h_fmin = 50 mm fails, but each cube stands in its own column (25 mm) and passes.
    In a row along the closing axis they are one column: 50 mm, as the paper's."""
    side = make_scene([("small_yellow_cube", 0.0, -0.0135, 0.0), ("small_yellow_cube", 0.0, 0.0135, 0.0)])
    ev = evaluate_grasps(side.polygons(), [0, 1], np.array([[0.0, 0.0, 0.0]]), columns=True)
    assert ev.h0[0] == pytest.approx(0.025) and ev.h_fmin == pytest.approx(0.050)
    assert not ev.diameter_ok[0] and ev.h_fmin_columns[0] == pytest.approx(0.025)
    assert ev.diameter_ok_columns[0] and ev.passed_columns[0] and not ev.passed[0]
    row = make_scene([("small_yellow_cube", -0.0135, 0.0, 0.0), ("small_yellow_cube", 0.0135, 0.0, 0.0)])
    ev = evaluate_grasps(row.polygons(), [0, 1], np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.5]]), columns=True)
    np.testing.assert_allclose(ev.h_fmin_columns, 0.050)
    np.testing.assert_array_equal(ev.diameter_ok_columns, ev.diameter_ok)


def test_columns_match_a_shapely_reckoning_on_cluttered_tables():
    """h_fmin_columns, batched, against shapely: each group object's part in S, its y-range,
    overlapping ranges summed into columns, the widest kept."""
    import shapely

    from mog_drake.geometry import create_obj_groups, gen_grasp_cands
    from mog_drake.geometry.gripper import to_grasp_frame
    from mog_drake.scenes import cluttered_scene

    g = GripperGeometry()
    box = shapely.box(-g.w_g / 2, -g.plate_width / 2, g.w_g / 2, g.plate_width / 2)
    checked = 0
    for seed in range(3):
        scene = cluttered_scene(np.random.default_rng(seed))
        polys = scene.polygons()
        for group in [grp for grp in create_obj_groups(polys.centers) if len(grp) > 1][:4]:
            cands = gen_grasp_cands(polys, group, g, 40, 7)
            ev = evaluate_grasps(polys, group, cands, g, columns=True)
            for b, grasp in enumerate(cands):
                spans = []
                for i in group:
                    part = shapely.Polygon(
                        to_grasp_frame(polys.polygon(i)[None], grasp[None])[0]
                    ).intersection(box)
                    if part.area > 1e-10:
                        spans.append((part.bounds[1], part.bounds[3], polys.d_fmin[i]))
                best, end, run = 0.0, -np.inf, 0.0
                for lo, hi, d in sorted(spans):
                    run, end = (run + d, max(end, hi)) if lo < end - 1e-9 else (d, hi)
                    best = max(best, run)
                assert ev.h_fmin_columns[b] == pytest.approx(best, abs=1e-9), (seed, group, b)
                checked += 1
    assert checked > 100


def test_the_planner_filters_with_the_diameter_condition_it_is_given():
    """The side-by-side cubes: with `diameter="columns"` more candidates of the pair pass the
    filter than with the paper's condition (the grasps across both, closing along x)."""
    from mog_drake.planning.planner import GraspConfig, GraspPlanner
    from mog_drake.planning.protocol import GraspResult

    class LiftsAnything:
        def check(self, scene, group, grasp):
            return GraspResult(True, lifted=list(group))

    side = make_scene([("small_yellow_cube", 0.0, -0.0135, 0.0), ("small_yellow_cube", 0.0, 0.0135, 0.0)])
    paper = GraspPlanner(LiftsAnything(), GraspConfig()).plan(side, [0, 1])
    columns = GraspPlanner(LiftsAnything(), GraspConfig(diameter_condition="columns")).plan(side, [0, 1])
    ev = evaluate_grasps(side.polygons(), [0, 1], columns.candidate_grasps, columns=True)
    assert paper.passed_conditions == int(ev.passed.sum())
    assert columns.passed_conditions == int(ev.passed_columns.sum()) > paper.passed_conditions
    assert columns.found and columns.tested == 1
    with pytest.raises(MogError, match="diameter"):
        GraspConfig(diameter_condition="friction")
