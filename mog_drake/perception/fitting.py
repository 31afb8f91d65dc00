"""Fitting library polygons to clusters of object points: symmetry, clusters, seedings, the
smooth score, and pushing overlapping fits apart."""

import math

import numpy as np
import shapely

from mog_drake.geometry.polygon import convex_hull_ccw, transform
from mog_drake.scenes import SceneObject


def symmetry_order(vertices: np.ndarray, tol: float = 2e-4) -> int:
    """Largest k in 1..8 such that turning the polygon by 2 pi / k about its centroid maps it
    onto itself, each vertex within ``tol`` (m) of one."""
    c = vertices.mean(axis=0)
    v = vertices - c
    for k in range(8, 1, -1):
        r = transform(v, 0.0, 0.0, 2 * math.pi / k)
        if all(np.min(np.linalg.norm(v - p, axis=1)) < tol for p in r):
            return k
    return 1


def _signed_distance(pts: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Max over a CCW convex polygon's edges of the outward distance: < 0 inside, and a lower
    bound of the true distance outside (exact near an edge)."""
    e = np.roll(poly, -1, axis=0) - poly
    n = np.stack([e[:, 1], -e[:, 0]], axis=1) / np.linalg.norm(e, axis=1, keepdims=True)
    return ((pts[:, None, :] - poly[None, :, :]) * n[None]).sum(-1).max(axis=1)


def _soft_inside(pts: np.ndarray, poly: np.ndarray, s: float) -> np.ndarray:
    """Smooth indicator of points inside a CCW convex polygon (1 deep inside, 0 outside)."""
    return 1.0 / (1.0 + np.exp(np.clip(_signed_distance(pts, poly) / s, -50, 50)))


def _kmeans(pts: np.ndarray, k: int, rng: np.random.Generator, iters: int = 20) -> np.ndarray:
    centres = pts[rng.choice(len(pts), size=k, replace=False)]
    for _ in range(iters):
        lab = np.argmin(((pts[:, None] - centres[None]) ** 2).sum(-1), axis=1)
        centres = np.array([pts[lab == j].mean(axis=0) if np.any(lab == j) else centres[j] for j in range(k)])
    return centres


# A fit weighs each point that is not of its object (table, another colour, already explained)
# this much against each of its object's points it covers, within this margin of its radius.
NEGATIVE_WEIGHT = 1.5
FIT_MARGIN = 0.004  # m


def _seedings(pts: np.ndarray, k: int, tries: int, rng: np.random.Generator):
    """Sets of k centres to fit k instances of one shape from, one set per try. k = 1: the
    centroid. k = 2: the centroids of the two halves of the cluster split at its median along
    each of 6 directions (k-means splits two bars lying side by side along the blob's longer
    side, across both bars, and no seeding finds the split between them). k > 2: ``tries``
    k-means seedings."""
    if k == 1:
        yield _kmeans(pts, 1, rng)
    elif k == 2:
        for a in np.arange(6) * np.pi / 6:
            s = pts @ np.array([np.cos(a), np.sin(a)])
            lo = s <= np.median(s)
            if lo.all() or not lo.any():
                continue
            yield np.array([pts[lo].mean(axis=0), pts[~lo].mean(axis=0)])
    else:
        for _ in range(tries):
            yield _kmeans(pts, k, rng)


def _clusters(pts: np.ndarray, link: float) -> list[np.ndarray]:
    """Connected clusters of 2-D points (points closer than ``link`` are connected), by grid labelling."""
    if len(pts) == 0:
        return []
    cell = np.floor(pts / link).astype(np.int64)
    keys = {}
    for i, c in enumerate(map(tuple, cell)):
        keys.setdefault(c, []).append(i)
    parent = {c: c for c in keys}

    def find(c):
        while parent[c] != c:
            parent[c] = parent[parent[c]]
            c = parent[c]
        return c

    for c in keys:
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                nb = (c[0] + dx, c[1] + dy)
                if nb in keys:
                    ra, rb = find(c), find(nb)
                    if ra != rb:
                        parent[ra] = rb
    groups: dict = {}
    for c, idx in keys.items():
        groups.setdefault(find(c), []).extend(idx)
    return [np.array(sorted(v)) for v in groups.values()]


def _outline(pts: np.ndarray, tol: float = 0.001) -> np.ndarray | None:
    """Convex hull (CCW) of 2-D points, simplified to ``tol``; None if it has no area."""
    hull = shapely.convex_hull(shapely.MultiPoint(pts)).simplify(tol)
    if not isinstance(hull, shapely.Polygon) or hull.area <= tol**2:
        return None
    return convex_hull_ccw(np.asarray(hull.exterior.coords)[:-1])


def _penetration(a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """Smallest translation of convex polygon ``a`` that separates it from ``b`` (separating
    axis theorem), or None if they do not overlap."""
    best = None
    for poly in (a, b):
        e = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([e[:, 1], -e[:, 0]], axis=1) / np.linalg.norm(e, axis=1, keepdims=True)
        for n in normals:
            pa, pb = a @ n, b @ n
            depth = min(pa.max() - pb.min(), pb.max() - pa.min())
            if depth <= 0:
                return None
            if best is None or depth < best[0]:
                sign = -1.0 if pa.mean() < pb.mean() else 1.0
                best = (depth, sign * n)
    return best[1] * best[0]


def separate_overlaps(objects, library, gap: float = 2e-4, iterations: int = 20):
    """Fitted polygons of touching objects can overlap by a fraction of a millimetre; real
    prisms cannot, and a physics check started from interpenetrating prisms starts with an
    explosion. Each overlapping pair is pushed apart along its separating axis, half each,
    until none overlaps. Returns (objects, number of corrections made)."""
    objs = list(objects)
    moved = 0
    for _ in range(iterations):
        polys = [transform(library[o.shape].vertices, o.x, o.y, o.theta) for o in objs]
        centres = np.array([p.mean(axis=0) for p in polys]).reshape(-1, 2)
        radii = np.array([np.linalg.norm(p - p.mean(axis=0), axis=1).max() for p in polys])
        changed = False
        for i in range(len(objs)):
            for j in range(i + 1, len(objs)):
                if np.linalg.norm(centres[i] - centres[j]) > radii[i] + radii[j]:
                    continue
                d = _penetration(polys[i], polys[j])
                if d is None:
                    continue
                step = d / 2 + gap / 2 * d / np.linalg.norm(d)
                for k, sgn in ((i, 1.0), (j, -1.0)):
                    o = objs[k]
                    objs[k] = SceneObject(o.shape, o.x + sgn * step[0], o.y + sgn * step[1], o.theta)
                    polys[k] = polys[k] + sgn * step
                    centres[k] = centres[k] + sgn * step
                moved += 1
                changed = True
        if not changed:
            break
    return objs, moved


class PointIndex:
    """Points sorted along x once, so the points within ``r`` of a centre are found from a
    narrow x band, not a scan of all of them. Returned in their original order (sums over them
    then add up in the same order as a full scan's)."""

    def __init__(self, points: np.ndarray):
        self.points = np.asarray(points, float)
        self._order = np.argsort(self.points[:, 0], kind="stable")
        self._x = self.points[self._order, 0]

    def within(self, centre, r: float) -> np.ndarray:
        lo, hi = np.searchsorted(self._x, [centre[0] - r, centre[0] + r], side="left")
        idx = np.sort(self._order[lo:hi])
        band = self.points[idx]
        return band[np.linalg.norm(band - centre, axis=1) < r]
