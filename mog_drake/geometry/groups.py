"""CreateObjGroups and RankObjGroups of the picking algorithm (paper Alg. 1, Sec. 6.1)."""

from __future__ import annotations

import numpy as np
import shapely

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
    hoods = []
    for i in range(len(c)):
        g = tuple(int(j) for j in np.flatnonzero(d[i] <= radius + LENGTH_TOL))
        if len(g) > 1 and g not in hoods:
            hoods.append(g)
    sets = [set(g) for g in hoods]
    multi = [g for g, s in zip(hoods, sets) if not any(s < other for other in sets)]
    return multi + [(i,) for i in range(len(c))]


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
