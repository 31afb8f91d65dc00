"""GenGraspCands and RankGraspCands of the grasp planner (paper Alg. 2, Sec. 6.2)."""

from __future__ import annotations

import numpy as np

from mog_drake.geometry.conditions import GraspEvaluation, PolygonSet, evaluate_grasps, jaw_collision_free
from mog_drake.geometry.gripper import GripperGeometry
from mog_drake.geometry.polygon import axis_gap, convex_hull_ccw, polygon_area


def _strictly_inside(hull: np.ndarray, pts: np.ndarray) -> np.ndarray:
    a = hull
    b = np.roll(hull, -1, axis=0)
    cross = (b[:, 0] - a[:, 0])[None] * (pts[:, 1:2] - a[:, 1][None]) - (b[:, 1] - a[:, 1])[None] * (
        pts[:, 0:1] - a[:, 0][None]
    )
    return np.all(cross > 0, axis=1)


def hull_positions(hull: np.ndarray, n: int) -> np.ndarray:
    """Up to ``n`` points on a square grid that uniformly covers the inside of a convex hull.

    The grid is centred on the hull's bounding box; its spacing is the smallest (found by
    bisection) that leaves at most ``n`` points strictly inside the hull. Deterministic.
    """
    if n < 1:
        return np.zeros((0, 2))
    lo_xy, hi_xy = hull.min(axis=0), hull.max(axis=0)
    centre, size = (lo_xy + hi_xy) / 2, hi_xy - lo_xy

    def grid(s: float) -> np.ndarray:
        nx, ny = int(size[0] // s) + 1, int(size[1] // s) + 1
        xs = centre[0] + (np.arange(nx) - (nx - 1) / 2) * s
        ys = centre[1] + (np.arange(ny) - (ny - 1) / 2) * s
        g = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)
        return g[_strictly_inside(hull, g)]

    s0 = np.sqrt(max(abs(polygon_area(hull)), 1e-12) / n)
    s_lo, s_hi = 0.5 * s0, 2.0 * s0
    while len(grid(s_hi)) > n:  # thin hulls: widen the bracket
        s_lo, s_hi = s_hi, 2.0 * s_hi
    best = grid(s_hi)
    for _ in range(14):
        mid = 0.5 * (s_lo + s_hi)
        g = grid(mid)
        if len(g) <= n:
            s_hi, best = mid, g
        else:
            s_lo = mid
    if len(best) == 0:
        best = hull.mean(axis=0, keepdims=True)
    return best


def edge_normal_angles(polys: PolygonSet, group, tol: float = 1e-3) -> np.ndarray:
    """The distinct directions, modulo pi and in [0, pi), of the group's edge normals: the
    closing axes along which the jaws meet an edge of some object flat. Ordered by the
    summed length of the edges each one is normal to, longest first (the broadest faces)."""
    angles, lengths = [], []
    for i in group:
        v = polys.polygon(int(i))
        d = np.roll(v, -1, axis=0) - v
        angles.append(np.remainder(np.arctan2(d[:, 1], d[:, 0]) + np.pi / 2, np.pi))
        lengths.append(np.hypot(d[:, 0], d[:, 1]))
    angles, lengths = np.concatenate(angles), np.concatenate(lengths)
    dirs: list[float] = []
    weight: list[float] = []
    for a, w in zip(angles, lengths):
        for k, b in enumerate(dirs):
            if axis_gap(a, b) <= tol:
                weight[k] += w
                break
        else:
            dirs.append(float(a))
            weight.append(float(w))
    order = sorted(range(len(dirs)), key=lambda k: (-weight[k], dirs[k]))
    return np.asarray([dirs[k] for k in order])


def candidate_grasps(
    polys: PolygonSet, group, n_positions: int = 70, n_orientations: int = 7, edge_orientations: bool = False
) -> np.ndarray:
    """All Np x Ntheta grasps u = (x, y, theta): positions covering the group's convex hull,
    orientations k pi / Ntheta, k = 0..Ntheta-1 (a parallel-jaw grasp is symmetric under pi).

    ``edge_orientations`` (an extension, off for the paper's experiments) adds a first block of
    Np grasps per edge-normal direction of the group (`edge_normal_angles`), so that ranking
    ties, which keep generation order, go to jaws parallel to an object's edges; grid
    orientations within 0.01 rad of an edge direction are then left out as repeats.
    """
    pts = np.concatenate([polys.polygon(int(i)) for i in group])
    hull = convex_hull_ccw(pts)
    if len(hull) < 3:
        pos = pts.mean(axis=0, keepdims=True)
    else:
        pos = hull_positions(hull, n_positions)
    th = np.arange(n_orientations) * np.pi / n_orientations
    blocks = []
    if edge_orientations:
        edges = edge_normal_angles(polys, group)
        th = th[axis_gap(th[:, None], edges[None, :]).min(axis=1) > 0.01]
        blocks.append(edges)
    blocks.append(th)
    return np.concatenate(
        [np.column_stack([np.repeat(pos, len(b), axis=0), np.tile(b, len(pos))]) for b in blocks if len(b)]
    )


def gen_grasp_cands(
    polys: PolygonSet,
    group,
    gripper: GripperGeometry | None = None,
    n_positions: int = 70,
    n_orientations: int = 7,
    edge_orientations: bool = False,
) -> np.ndarray:
    """GenGraspCands(): the collision-free grasps (B', 3) of the Np x Ntheta candidates.

    Candidates whose jaws overlap any object, in or out of the group, are rejected (Sec. 6.2).
    """
    grasps = candidate_grasps(polys, group, n_positions, n_orientations, edge_orientations)
    return grasps[jaw_collision_free(polys, grasps, gripper)]


def rank_grasp_cands(ev: GraspEvaluation) -> np.ndarray:
    """RankGraspCands(): candidate indices by decreasing total intersection area A_T.

    Ties keep generation order (stable sort), so the ranking is deterministic.
    """
    return np.argsort(-ev.area_total, kind="stable")


def ranked_candidates(
    polys: PolygonSet,
    group,
    gripper: GripperGeometry | None = None,
    n_positions: int = 70,
    n_orientations: int = 7,
) -> tuple[GraspEvaluation, np.ndarray]:
    """Every Np x Ntheta candidate of ``group``, colliding ones included, evaluated, and their
    ranking by total intersection area (`rank_grasp_cands`): what the tools show and draw."""
    ev = evaluate_grasps(polys, group, candidate_grasps(polys, group, n_positions, n_orientations), gripper)
    return ev, rank_grasp_cands(ev)
