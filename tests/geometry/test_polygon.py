import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from mog_drake.errors import MogError
from mog_drake.geometry.polygon import final_diameters, transform, validate_convex_polygon


def regular(n, side):
    r = side / (2 * math.sin(math.pi / n))
    a = np.arange(n) * 2 * math.pi / n
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


@pytest.mark.parametrize("w,h", [(0.05, 0.007), (0.03, 0.03), (0.012, 0.036)])
def test_rectangle_has_both_side_lengths(w, h):
    rect = np.array([[0, 0], [w, 0], [w, h], [0, h]])
    np.testing.assert_allclose(final_diameters(rect), sorted({w, h}), atol=1e-12)


def test_equilateral_triangle():
    a = 0.042
    np.testing.assert_allclose(final_diameters(regular(3, a)), [a * math.sqrt(3) / 2], atol=1e-12)


def test_regular_hexagon_excludes_vertex_vertex():
    s = 0.02
    # Flat-to-flat s*sqrt(3) only; the corner-to-corner 2s is a vertex-vertex grasp.
    np.testing.assert_allclose(final_diameters(regular(6, s)), [s * math.sqrt(3)], atol=1e-12)


def test_obtuse_triangle_vertex_foot_outside_edge_is_unstable():
    # Apex far to the right: its perpendicular foot on the base lies outside the base, so
    # the base/apex pair is not an equilibrium; only the pairs onto the long sides are.
    tri = np.array([[0.0, 0.0], [0.01, 0.0], [0.05, 0.01]])
    d = final_diameters(tri)
    base_height = 0.01
    assert not np.any(np.isclose(d, base_height))
    assert len(d) >= 1


# d_fmin in mm from the reference table of the 14 library shapes.
REFERENCE_D_FMIN_MM = {
    "thin_bar": 7.00,
    "thick_bar": 12.00,
    "blue_quad": 29.58,
    "yellow_quad": 23.94,
    "small_yellow_cube": 25.00,
    "orange_quad": 28.00,
    "dark_yellow_cube": 29.00,
    "red_triangle": 36.37,
    "green_trapezoid": 33.23,
    "orange_trapezoid": 30.08,
    "blue_pentagon": 35.39,
    "pink_pentagon": 36.64,
    "large_hexagon": 34.73,
    "small_hexagon": 29.58,
}


def test_library_matches_reference(lib):
    assert set(lib.shapes) == set(REFERENCE_D_FMIN_MM)
    for name, d in REFERENCE_D_FMIN_MM.items():
        assert lib[name].d_fmin * 1e3 == pytest.approx(d, abs=0.01), name


def test_isrr33_inventory(lib):
    inv = lib.inventory("isrr33")
    assert len(inv) == 33
    assert inv.count("thin_bar") == 13 and inv.count("thick_bar") == 11 and inv.count("large_hexagon") == 2


@pytest.mark.parametrize(
    "pts,msg",
    [
        ([[0, 0], [1, 0], [1, 1], [0.9, 0.2]], "not a convex polygon"),
        ([[0, 0], [1, 0]], "at least 3"),
        ([[0, 0], [1, 0], [1, 0], [0, 1]], "repeated"),
        ([[0, 0], [1, 1], [2, 2]], "collinear"),
        ([[0, 0], [1, 0], [float("nan"), 1]], "non-finite"),
        ([[0, 0], [1, 0], [float("inf"), 1]], "non-finite"),
        ([[0, 0], [1, 0], [0.5, 0], [0.5, 1]], "not a corner"),
        ([[0, 0], [0, 1e-8], [0.03, 0.03], [0.03, -0.03]], "an edge is 1e-08 m long, under 1e-06 m"),
        ("abc", "vertices"),
    ],
)
def test_bad_polygons_are_refused_by_name(pts, msg):
    with pytest.raises(MogError, match=msg) as e:
        validate_convex_polygon(pts, "my_shape")
    assert "my_shape" in str(e.value)


def test_vertex_order_does_not_matter():
    pts = np.array([[0.0, 0.0], [0.02, 0.0], [0.02, 0.01], [0.0, 0.01]])
    a = validate_convex_polygon(pts, "a")
    b = validate_convex_polygon(pts[[2, 0, 3, 1]], "b")
    np.testing.assert_allclose(final_diameters(a), final_diameters(b))


@settings(max_examples=60, deadline=None)
@given(st.sampled_from(sorted(REFERENCE_D_FMIN_MM)), st.floats(-1, 1), st.floats(-1, 1), st.floats(-7, 7))
def test_final_diameters_are_rigid_motion_invariant(name, x, y, th):
    from mog_drake.scenes import default_library

    v = default_library()[name].vertices
    moved = transform(v, x, y, th)
    np.testing.assert_allclose(final_diameters(moved), final_diameters(v), atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05)), min_size=3, max_size=12))
# Found by this test: the hull kept its leftmost point although it lay on an edge, which split
# the edge in two and hid the triangle's only stable grasp.
@example([(0.0, 0.0), (0.0, 0.03125), (0.03125, 0.0), (4.383042186366938e-82, -0.03125)])
# Also found by it: a point 1e-12 m off an edge (or off a corner) was kept by one chain of the
# hull and dropped by the other, leaving a sliver edge and no (or the wrong) stable grasps.
@example([(0.0, 0.0), (0.0, -0.03125), (0.03125, 0.0), (1e-12, 0.03125)])
@example([(0.0, 0.0), (0.0, 1e-12), (0.03125, 0.0), (0.0078125, 0.03125)])
@example([(0.0, 0.0), (0.0, 1e-06), (0.03125, 0.03125), (0.03125, -0.015625)])
# And: a 0.06 mm sliver's minimum width has its foot 6e-8 m from a corner, inside the contact
# tolerance, so it was taken for a vertex-vertex contact and the sliver had no stable grasp.
@example([(0.0, 0.03125), (0.0, -0.03125), (6.103515625e-05, 0.03125)])
def test_d_fmin_is_the_minimum_width(points):
    """For any convex polygon, d_fmin equals the minimum width over all directions."""
    from mog_drake.geometry.polygon import MIN_EDGE, convex_hull_ccw, polygon_area

    hull = convex_hull_ccw(np.array(points))
    if len(hull) < 3 or polygon_area(hull) < 1e-6:
        return
    # Shapes are refused with an edge under MIN_EDGE (final_diameters resolves 1e-7 m).
    if np.linalg.norm(np.roll(hull, -1, axis=0) - hull, axis=1).min() < MIN_EDGE:
        return
    d = final_diameters(hull)
    assert len(d) >= 1
    # The minimum width of a convex polygon is attained normal to one of its edges...
    e = np.roll(hull, -1, axis=0) - hull
    normals = np.column_stack([e[:, 1], -e[:, 0]]) / np.linalg.norm(e, axis=1, keepdims=True)
    proj = hull @ normals.T
    assert d.min() == pytest.approx(float((proj.max(0) - proj.min(0)).min()), abs=1e-12)
    # ...and no sampled direction is narrower.
    ang = np.linspace(0, np.pi, 2001)
    proj = hull @ np.column_stack([np.cos(ang), np.sin(ang)]).T
    assert d.min() <= float((proj.max(0) - proj.min(0)).min()) + 1e-12
