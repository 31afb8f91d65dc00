"""CreateObjGroups and RankObjGroups of the picking algorithm (paper Alg. 1, Sec. 6.1)."""

from __future__ import annotations

import numpy as np
import shapely

from mog_drake.errors import MogError
from mog_drake.geometry.conditions import AREA_EPS, evaluate_grasps
from mog_drake.geometry.polygon import LENGTH_TOL

#: Grouping radius used on the authors' robot (m): a little under half the 75 mm stroke.
DEFAULT_GROUP_RADIUS = 0.035


def create_obj_groups(centers, radius: float = DEFAULT_GROUP_RADIUS) -> list[tuple[int, ...]]:
    """CreateObjGroups(): for each object, the objects whose centres lie within ``radius`` of
    its centre (neighbourhoods, not transitive clusters). Multi-object groups that are a
    strict subset of another group, and duplicates, are removed; every single object is kept
    as its own group. Returns sorted index tuples: multi-object groups first (in order of
    their seed object), then the singles.
    """
    c = np.asarray(centers, dtype=float).reshape(-1, 2)
    if len(c) == 0:
        return []
    d = np.linalg.norm(c[:, None, :] - c[None, :, :], axis=2)
    return _neighbourhoods(d, radius + LENGTH_TOL) + [(i,) for i in range(len(c))]


def _neighbourhoods(d: np.ndarray, within: float) -> list[tuple[int, ...]]:
    """For each object i, the objects j with ``d[i, j] <= within`` (i itself included), as
    sorted tuples in order of i: only those of two or more objects, without duplicates, and
    without any that is a strict subset of another."""
    hoods = []
    for i in range(len(d)):
        g = tuple(int(j) for j in np.flatnonzero(d[i] <= within))
        if len(g) > 1 and g not in hoods:
            hoods.append(g)
    sets = [set(g) for g in hoods]
    return [g for g, s in zip(hoods, sets) if not any(s < other for other in sets)]


def rank_obj_groups(groups, d_fmin, w_g: float) -> list[tuple[int, ...]]:
    """RankObjGroups(): groups by decreasing size (stable), skipping any group whose summed
    d_fmin exceeds the stroke w_g (it cannot fit between the jaws)."""
    d = np.asarray(d_fmin, dtype=float)
    feasible = [g for g in groups if d[list(g)].sum() <= w_g + LENGTH_TOL]
    return sorted(feasible, key=lambda g: -len(g))


def objects_in_reach(scene, group, gripper, margin: float) -> list[int]:
    """The group plus every object whose bounding circle comes within the gripper's reach of
    the group's convex hull (where every candidate of the group lies), plus ``margin``."""
    polys = scene.polygons()
    hull = shapely.convex_hull(shapely.MultiPoint(np.concatenate([polys.polygon(int(i)) for i in group])))
    d = shapely.distance(hull, shapely.points(polys.centers))
    near = np.flatnonzero(d < polys.radii + gripper.reach_radius + margin)
    return sorted(set(int(i) for i in near) | set(int(i) for i in group))


def objects_at_grasp(scene, group, grasp, gripper, margin: float) -> list[int]:
    """The group plus every object that the check of one grasp u = ``grasp`` can touch: whose
    outline comes within ``margin`` of the open jaws' swept rectangle (jaw to jaw, both jaws
    included) or of a group object's bounding disc (a squeezed object slides and turns about
    its centre). A tighter set than `objects_in_reach`, which holds what any grasp of the
    group can touch."""
    polys = scene.polygons()
    x0, _, y0, y1 = gripper.boxes()["left_jaw"]
    corners = np.array([[x0, y0], [-x0, y0], [-x0, y1], [x0, y1]])
    x, y, th = (float(v) for v in grasp)
    c, s = np.cos(th), np.sin(th)
    swept = shapely.Polygon(
        np.column_stack(
            [c * corners[:, 0] - s * corners[:, 1] + x, s * corners[:, 0] + c * corners[:, 1] + y]
        )
    )
    g = [int(i) for i in group]
    reach = shapely.union_all([swept, *shapely.buffer(shapely.points(polys.centers[g]), polys.radii[g])])
    outlines = np.array([shapely.Polygon(polys.polygon(i)) for i in range(len(polys))], dtype=object)
    near = np.flatnonzero(shapely.distance(reach, outlines) < margin)
    return sorted(set(int(i) for i in near) | set(g))


def adjacent_groups(polys, gap: float, w_g: float) -> list[tuple[int, ...]]:
    """For each object, it and the objects whose outlines come within ``gap`` (m) of its own,
    as groups (sorted tuples, largest first, duplicates and strict subsets of another dropped,
    and any whose summed d_fmin exceeds the stroke ``w_g`` dropped): the groups that pushes
    make, which the radius of `create_obj_groups` misses when objects meet end to end."""
    if len(polys) < 2:
        return []
    shp = np.array([shapely.Polygon(polys.polygon(i)) for i in range(len(polys))], dtype=object)
    d = shapely.distance(shp[:, None], shp[None, :])
    return rank_obj_groups(_neighbourhoods(d, gap), polys.d_fmin, w_g)


#: Grid of the conditions grouping (`condition_groups`): positions every STEP metres over the
#: objects, closing axes k pi / N_ORIENTATIONS.
CONDITION_GROUPS_STEP = 0.005  # m
CONDITION_GROUPS_ORIENTATIONS = 12


def condition_groups(
    polys,
    gripper,
    step: float = CONDITION_GROUPS_STEP,
    n_orientations: int = CONDITION_GROUPS_ORIENTATIONS,
) -> list[tuple[int, ...]]:
    """CreateObjGroups and RankObjGroups from the necessary conditions (an extension of Alg. 1;
    the paper groups by a radius around each centre, `create_obj_groups`).

    A grid of grasps covers the table: positions every ``step`` over the objects' extent,
    closing axes k pi / ``n_orientations``. Each collision-free grasp of the grid names a set:
    the objects with material inside its region S. The set is a group if the grasp satisfies
    both necessary conditions for it (h0 >= its summed d_fmin, A_i > 0 for each member). A
    grasp closing on objects whose centres are up to a stroke apart, bars side by side in a
    row, gives a group the radius misses.

    Multi-object groups that are a strict subset of another are removed, as in
    `create_obj_groups`. Returned ranked: by decreasing size, then by decreasing best total
    intersection area A_T over the grid grasps naming the group (the planner's own ranking),
    then every single object as its own group, in index order."""
    n = len(polys)
    if n == 0:
        return []
    singles = [(i,) for i in range(n)]
    if n == 1:
        return singles
    pts = polys.vertices.reshape(-1, 2)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    xs = np.arange(lo[0], hi[0] + step / 2, step)
    ys = np.arange(lo[1], hi[1] + step / 2, step)
    th = np.arange(n_orientations) * np.pi / n_orientations
    X, Y = np.meshgrid(xs, ys)
    pos = np.column_stack([X.ravel(), Y.ravel()])
    # Keep positions within reach of some object: a grasp there can name a set.
    near = np.linalg.norm(pos[:, None, :] - polys.centers[None, :, :], axis=2)
    pos = pos[(near < polys.radii[None, :] + gripper.reach_radius).any(axis=1)]
    grasps = np.column_stack([np.repeat(pos, len(th), axis=0), np.tile(th, len(pos))])
    ev = evaluate_grasps(polys, np.arange(n), grasps, gripper)
    member = ev.in_s & ev.collision_free[:, None]
    member &= ev.areas > AREA_EPS
    size = member.sum(axis=1)
    h_fmin = member.astype(float) @ polys.d_fmin
    ok = (size >= 2) & (ev.h0 >= h_fmin - LENGTH_TOL)
    if not ok.any():
        return singles
    sets, inverse = np.unique(member[ok], axis=0, return_inverse=True)
    score = np.full(len(sets), -np.inf)
    np.maximum.at(score, inverse.ravel(), ev.areas[ok].sum(axis=1))
    # Strict subsets of another set out.
    counts = sets.sum(axis=1)
    inter = sets.astype(int) @ sets.T.astype(int)
    subset = (inter == counts[:, None]) & (counts[:, None] < counts[None, :])
    keep = ~subset.any(axis=1)
    order = sorted(np.flatnonzero(keep), key=lambda k: (-counts[k], -score[k]))
    return [tuple(int(i) for i in np.flatnonzero(sets[k])) for k in order] + singles


GROUPINGS = ("radius", "conditions")  # CreateObjGroups: the paper's, or by the conditions


def ranked_groups(
    polys, gripper, grouping: str = "radius", radius: float = DEFAULT_GROUP_RADIUS, w_g: float | None = None
) -> list[tuple[int, ...]]:
    """CreateObjGroups then RankObjGroups as ``grouping`` says: "radius" (the paper's,
    `create_obj_groups` with ``radius``, then `rank_obj_groups` for a stroke ``w_g``, default
    the gripper's) or "conditions" (`condition_groups` for ``gripper``)."""
    if grouping == "conditions":
        return condition_groups(polys, gripper)
    if grouping == "radius":
        return rank_obj_groups(
            create_obj_groups(polys.centers, radius), polys.d_fmin, gripper.w_g if w_g is None else w_g
        )
    raise MogError(f"grouping must be one of {GROUPINGS}, got {grouping!r}")
