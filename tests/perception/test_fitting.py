"""Perception's pieces on synthetic images: the polygon score, components, the search."""

import math

import numpy as np
import pytest

from mog_drake.perception.fitting import PolygonScore, components, pixels_inside, quadratic_search


def _square_plane(scale: float = 10.0, u0: float = 30.0, v0: float = 40.0) -> np.ndarray:
    """A homography from the plane to pixels: ``scale`` pixels per unit, origin at (u0, v0)."""
    return np.array([[scale, 0.0, u0], [0.0, scale, v0], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("theta", [0.0, 0.3, 1.1, 2.5])
def test_polygon_score_of_uniform_evidence_is_the_area_in_pixels(theta):
    """Green's theorem: over evidence 1 everywhere the score is the polygon's area in pixels,
    whatever its pose, winding or the window's origin; it also matches the count of pixel
    centres inside it to within the outline's partly covered pixels."""
    rng = np.random.default_rng(1)
    tri = np.array([[-1.2, -0.7], [1.5, -0.4], [0.1, 1.6]])
    for verts in (tri, tri[::-1]):
        score = PolygonScore(np.ones((80, 100)), (5, 7), _square_plane(), verts, samples=64)
        x, y = rng.uniform(-0.5, 0.5, 2)
        s = score(np.array([[x, y, theta]]))[0]
        (ax, ay), (bx, by) = tri[1] - tri[0], tri[2] - tri[0]
        area = 0.5 * abs(ax * by - ay * bx) * 100
        assert s == pytest.approx(area, rel=1e-3)
        poly = score.polygons(np.array([[x, y, theta]]))[0] - [0.5, 0.0] + [5, 7]
        inside = pixels_inside(poly, (80, 100), (5, 7)).sum()
        perimeter = np.linalg.norm(np.roll(poly, -1, axis=0) - poly, axis=1).sum()
        assert abs(inside - area) < 0.5 * perimeter


def test_polygon_score_with_samples_per_edge_is_the_area_and_stacks_faces_of_any_vertex_count():
    """Samples per edge (a thin bar's short ends need few) keep the score exact on uniform
    evidence; a stack of windows holding faces with different vertex counts and samples
    scores each pose as its own face's score does (the shorter face padded with edges of no
    length before its closing edge)."""
    rng = np.random.default_rng(2)
    tri = np.array([[-1.2, -0.7], [1.5, -0.4], [0.1, 1.6]])
    bar = np.array([[-2.0, -0.3], [2.0, -0.3], [2.0, 0.3], [-2.0, 0.3]])
    E = rng.standard_normal((80, 100))
    t_score = PolygonScore(E, (5, 7), _square_plane(), tri, samples=[30, 20, 25])
    b_score = PolygonScore(E, (2, 3), _square_plane(9.0), bar, samples=[40, 6, 40, 6])
    flat = PolygonScore(np.ones((80, 100)), (5, 7), _square_plane(), bar, samples=[40, 6, 40, 6])
    assert flat(np.array([[0.1, -0.2, 0.4]]))[0] == pytest.approx(4.0 * 0.6 * 100, rel=1e-3)
    poses = np.column_stack([rng.uniform(-0.5, 0.5, (6, 2)), rng.uniform(0, 3, 6)])
    both = PolygonScore.stack([t_score, b_score, t_score])
    for owner, own in ((0, t_score), (1, b_score), (2, t_score)):
        assert both(poses, owner=np.full(6, owner)) == pytest.approx(own(poses), rel=1e-5, abs=1e-3)
    mixed = np.array([0, 1, 2, 1, 0, 1])
    expected = [(t_score, b_score, t_score)[o](poses[i : i + 1])[0] for i, o in enumerate(mixed)]
    assert both(poses, owner=mixed) == pytest.approx(expected, rel=1e-5, abs=1e-3)
    with pytest.raises(ValueError, match="at least one sample"):
        PolygonScore(E, (0, 0), _square_plane(), tri, samples=[3, 0, 3])


def test_polygon_score_moves_with_sub_pixel_shifts_and_peaks_on_the_object():
    """Evidence +1 on a square object and -1.5 around it: the score grows continuously as a
    square of the same size slides onto it, and is largest where it sits on it."""
    E = np.full((60, 60), -1.5)
    E[20:40, 20:40] = 1.0  # pixel centres 20..39: the square [19.5, 39.5] in pixel coordinates
    sq = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    score = PolygonScore(E, (0, 0), _square_plane(10.0, 29.5, 29.5), sq, samples=40)
    xs = np.linspace(-0.3, 0.3, 61)
    s = score(np.column_stack([xs, np.zeros_like(xs), np.zeros_like(xs)]))
    assert xs[np.argmax(s)] == pytest.approx(0.0, abs=0.011)
    assert np.all(np.abs(np.diff(s)) < 2.5 * 20 * 0.1 + 1e-6)  # no jumps: at most a strip per step
    best, value = quadratic_search(score, np.array([[0.12, -0.08, 0.05]]), np.array([0.2, 0.2, 0.05]), 1e-3)
    assert best[:2] == pytest.approx([0.0, 0.0], abs=0.02) and math.remainder(
        best[2], math.pi / 2
    ) == pytest.approx(0.0, abs=0.01)
    # 400 pixels, less the rows the running sum is interpolated across at the top and bottom
    # edges (half a row each, read as the average of a -1.5 and a +1 row on the way in).
    assert value == pytest.approx(400.0 - 2 * 20 * 0.3125, abs=0.5)


def test_components_bridge_a_missing_row_but_not_a_gap():
    img = np.zeros((20, 30), dtype=bool)
    img[2:8, 2:8] = True
    img[5, 2:8] = False  # one missing row: still one face
    img[2:8, 10:14] = True  # 2 pixels from the first: bridged (bridge = 1 grows each by 1)
    img[12:16, 2:6] = True  # 4 pixels below: separate
    labels, members = components(np.flatnonzero(img), img.shape)
    assert sorted(len(m) for m in members) == [16, 36 - 6 + 24]
    for k, m in enumerate(members, start=1):
        assert (labels.ravel()[m] == k).all() and np.all(np.diff(m) > 0)
    assert (labels[~img] == 0).all()


def test_shapes_whose_lone_fits_may_share_a_search():
    """Lone instances of shapes that cannot take each other's pixels are fitted in one batch:
    another colour, or one colour with tops more than two height bands apart (a thin bar and
    its 7 mm high side). A small cube (30 mm) and the same cube on its side (25 mm) can."""
    from mog_drake.perception import Perceiver

    p = Perceiver(table=(-0.3, 0.3, -0.4, 0.4))
    k = {n: i for i, n in enumerate(p.names)}
    assert not p._interact(k["thin_bar"], k["thick_bar"])
    assert not p._interact(k["thin_bar"], k["thin_bar:on_side"])
    assert p._interact(k["small_yellow_cube"], k["small_yellow_cube:on_side"])
    assert p._interact(k["thin_bar"], k["thin_bar"])
