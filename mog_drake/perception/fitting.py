"""Fitting library polygons to what the camera sees: symmetry, connected components, seedings,
the score of a polygon in the image, and pushing overlapping fits apart."""

import math

import numpy as np
import shapely
from scipy import ndimage

from mog_drake.geometry.polygon import convex_hull_ccw, convex_inside_distance, transform
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


def near_polygon(x: np.ndarray, y: np.ndarray, poly: np.ndarray, margin: float) -> np.ndarray:
    """Which points (arrays x, y of any one shape) lie inside a convex polygon or within
    ``margin`` of its edges' lines outside it (nan: False)."""
    return convex_inside_distance(poly, x, y) > -margin


def _kmeans(pts: np.ndarray, k: int, rng: np.random.Generator, iters: int = 20) -> np.ndarray:
    centres = pts[rng.choice(len(pts), size=k, replace=False)]
    for _ in range(iters):
        lab = np.argmin(((pts[:, None] - centres[None]) ** 2).sum(-1), axis=1)
        n = np.bincount(lab, minlength=k)
        sums = np.stack([np.bincount(lab, pts[:, 0], k), np.bincount(lab, pts[:, 1], k)], axis=1)
        centres = np.where(n[:, None] > 0, sums / np.maximum(n, 1)[:, None], centres)
    return centres


# A fit weighs each point that is not of its object (table, another colour, already explained)
# this much against each of its object's points it covers, within this margin of its radius.
NEGATIVE_WEIGHT = 1.5
FIT_MARGIN = 0.004  # m


def seedings(pts: np.ndarray, k: int, tries: int, rng: np.random.Generator):
    """Sets of k centres to fit k instances of one shape from, one set per try. k = 1: the
    centroid. k = 2: the centroids of the two halves of the cluster split at its median along
    each of ``tries + 1`` directions (k-means splits two bars lying side by side along the
    blob's longer side, across both bars, and no seeding finds the split between them).
    k > 2: the centroids of k slabs of equal count across each of the cluster's two principal
    axes (bars lying side by side in a row, which k-means cuts across), then ``tries`` k-means
    seedings."""
    if k == 1:
        yield pts.mean(axis=0)[None]
    elif k == 2:
        for a in np.arange(tries + 1) * np.pi / (tries + 1):
            s = pts @ np.array([np.cos(a), np.sin(a)])
            lo = s <= np.median(s)
            if lo.all() or not lo.any():
                continue
            yield np.array([pts[lo].mean(axis=0), pts[~lo].mean(axis=0)])
    else:
        _, _, axes = np.linalg.svd(pts - pts.mean(axis=0), full_matrices=False)
        for axis in axes:
            order = np.argsort(pts @ axis)
            yield np.array([pts[part].mean(axis=0) for part in np.array_split(order, k)])
        for _ in range(tries):
            yield _kmeans(pts, k, rng)


def outline(pts: np.ndarray, tol: float = 0.001) -> np.ndarray | None:
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
        e = poly[np.arange(1, len(poly) + 1) % len(poly)] - poly
        normals = np.stack([e[:, 1], -e[:, 0]], axis=1) / np.hypot(e[:, 0], e[:, 1])[:, None]
        for n in normals:
            pa, pb = a @ n, b @ n
            depth = min(pa.max() - pb.min(), pb.max() - pa.min())
            if depth <= 0:
                return None
            if best is None or depth < best[0]:
                sign = -1.0 if pa.mean() < pb.mean() else 1.0
                best = (depth, sign * n)
    return best[1] * best[0]


PAIR_SLACK = 0.005  # m


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
        # Pairs whose discs come within PAIR_SLACK of meeting, in (i, j) order: a pass moves
        # objects by fractions of a millimetre, so no other pair can come to overlap in it.
        clear = (
            np.hypot(*(centres[:, None, :] - centres[None, :, :]).transpose(2, 0, 1)) - radii[:, None] - radii
        )
        near = np.argwhere(np.triu(clear <= PAIR_SLACK, 1))
        changed = False
        for i, j in near.tolist():
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


def components(
    pixels: np.ndarray, shape: tuple[int, int], bridge: int = 1
) -> tuple[np.ndarray, list[np.ndarray]]:
    """Connected components of a set of pixels (flat indices into an image of ``shape``):
    (labels, members), labels an int image (0 off the set, k + 1 on component k), members[k]
    its flat pixel indices in ascending order. Pixels up to ``2 * bridge`` pixels apart are
    joined, so one missing row of depth does not split a top face in two: components are
    labelled (8-connected) on the set grown by ``bridge`` pixels."""
    labels = np.zeros(shape, dtype=np.int32)
    if len(pixels) == 0:
        return labels, []
    rows, cols = np.divmod(np.asarray(pixels), shape[1])
    pad = bridge + 1
    r0, r1 = max(int(rows.min()) - pad, 0), min(int(rows.max()) + pad + 1, shape[0])
    c0, c1 = max(int(cols.min()) - pad, 0), min(int(cols.max()) + pad + 1, shape[1])
    crop = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    crop[rows - r0, cols - c0] = True
    grown = ndimage.binary_dilation(crop, iterations=bridge) if bridge else crop
    lab, _ = ndimage.label(grown, structure=np.ones((3, 3), dtype=bool))
    lab = np.where(crop, lab, 0)
    labels[r0:r1, c0:c1] = lab
    cr, cc = np.nonzero(lab)
    lab_flat = lab[cr, cc]
    flat = (cr + r0) * shape[1] + (cc + c0)  # ascending, as np.nonzero runs row-major
    order = np.argsort(lab_flat, kind="stable")
    cuts = np.flatnonzero(np.diff(lab_flat[order])) + 1
    # Every grown component holds a pixel of the set: labels run 1..n, in members' order.
    return labels, np.split(flat[order], cuts)


class PolygonScore:
    """The score of a prism's top face at planar poses (x, y, theta): the sum of per-pixel
    ``evidence`` (+1 a pixel of the object, a negative weight a pixel that rules it out, 0 no
    evidence) over the pixels the face covers in the image, by Green's theorem: the integral
    over the projected polygon is the line integral around it of the evidence's running sum
    along each row, taken by the midpoint rule on each edge. A pose costs one look-up per
    sample, whatever the face's area. Pixels partly covered count in part (the running sum is
    interpolated), so the score changes continuously as the face moves by a fraction of a
    pixel.

    ``evidence`` (h, w): a window of the image, its pixel (0, 0) at image pixel ``origin``
    (u0, v0). ``plane``: the 3 x 3 homography from (x, y, 1) on the face's plane to
    homogeneous image coordinates. ``vertices`` (V, 2): the face in its body frame.
    ``samples``: per edge, an int for every edge or a count for each (about one per pixel of
    the edge's length: a thin bar's short ends need few). `PolygonScore.stack` joins scores
    in several windows (several instances fitted at once, of one shape or of several): each
    pose then names its window (``owner``)."""

    def __init__(self, evidence: np.ndarray, origin, plane: np.ndarray, vertices: np.ndarray, samples):
        h, w = evidence.shape
        if h < 2 or w < 2:
            raise ValueError(f"a score window must be at least 2 x 2 pixels, got {h} x {w}")
        C = np.zeros((h, w + 1), dtype=np.float32)  # sums of at most a few thousand: exact enough
        np.cumsum(evidence, axis=1, out=C[:, 1:])
        self._C = C.ravel()
        self._off = np.zeros(1, dtype=np.intp)
        self._h, self._w = np.array([h], dtype=np.intp), np.array([w], dtype=np.intp)
        # The homography to window coordinates, and the column's half-pixel shift (pixel u
        # covers [u - 0.5, u + 0.5]: the running sum at column coordinate u + 0.5) folded in.
        shift = np.array([[1.0, 0.0, 0.5 - origin[0]], [0.0, 1.0, -origin[1]], [0.0, 0.0, 1.0]])
        self._H = (shift @ np.asarray(plane, float))[None]
        v = np.asarray(vertices, float)
        self._V = np.vstack([v.T, np.ones(len(v))])[None]  # (windows, 3, V)
        self._next = np.arange(1, len(v) + 1) % len(v)
        counts = np.broadcast_to(np.asarray(samples, dtype=np.intp), (len(v),))
        if np.any(counts < 1):
            raise ValueError(f"every edge needs at least one sample, got {counts.tolist()}")
        self._counts = counts[None].copy()  # (windows, V)
        self._tables: dict = {}

    @classmethod
    def stack(cls, scores: list["PolygonScore"]) -> "PolygonScore":
        """One score over the windows of ``scores``. Faces with fewer vertices than the most
        are padded by repeating their last vertex, an edge of no length and no samples."""
        out = cls.__new__(cls)
        sizes = [len(x._C) for x in scores]
        out._C = np.concatenate([x._C for x in scores])
        out._off = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.intp)
        out._h = np.concatenate([x._h for x in scores])
        out._w = np.concatenate([x._w for x in scores])
        out._H = np.concatenate([x._H for x in scores])
        n = max(x._V.shape[2] for x in scores)
        if all(x._V.shape == scores[0]._V.shape and np.array_equal(x._V, scores[0]._V) for x in scores):
            out._V = scores[0]._V
        else:
            out._V = np.concatenate(
                [np.concatenate([x._V] + [x._V[:, :, -1:]] * (n - x._V.shape[2]), axis=2) for x in scores]
            )
        # A padded face's closing edge is its last: the edges of no length come before it.
        if all(np.array_equal(x._counts, scores[0]._counts) for x in scores):
            out._counts = scores[0]._counts  # one table of samples serves every window
        else:
            out._counts = np.concatenate(
                [
                    np.concatenate(
                        [
                            x._counts[:, :-1],
                            np.zeros((len(x._counts), n - x._counts.shape[1]), np.intp),
                            x._counts[:, -1:],
                        ],
                        axis=1,
                    )
                    for x in scores
                ]
            )
        out._next = np.arange(1, n + 1) % n
        out._tables = {}
        return out

    def _table(self, coarse: int):
        """Each window's samples, padded to the most (weight 0): the edge each lies on (W, M),
        where along it (W, M) and its weight, 1 / the edge's samples (W, M). With ``coarse``
        > 1, each edge takes that many times fewer samples (at least 2)."""
        if coarse not in self._tables:
            counts = self._counts
            if coarse > 1:
                counts = np.where(counts > 0, np.maximum(counts // coarse, 2), 0)
            M = int(counts.sum(axis=1).max())
            W = len(counts)
            edge = np.zeros((W, M), np.intp)
            t = np.zeros((W, M), np.float32)
            wt = np.zeros((W, M), np.float32)
            for i, row in enumerate(counts):
                j = 0
                for e, n in enumerate(row):
                    if n == 0:
                        continue
                    edge[i, j : j + n] = e
                    t[i, j : j + n] = (np.arange(n) + 0.5) / n
                    wt[i, j : j + n] = 1.0 / n
                    j += n
            self._tables[coarse] = (edge, t, wt)
        return self._tables[coarse]

    def polygons(self, poses: np.ndarray, owner=None) -> np.ndarray:
        """poses (N, 3) -> (N, V, 2) the face's corners in window coordinates (columns shifted
        by half a pixel, as the running sum is read)."""
        c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
        owner = np.zeros(len(poses), np.intp) if owner is None else owner
        H = self._H[owner]  # (N, 3, 3)
        # H @ [[c, -s, x], [s, c, y], [0, 0, 1]]: each pose's homography from body to window.
        M = np.empty((len(poses), 3, 3))
        M[:, :, 0] = c * H[:, :, 0] + s * H[:, :, 1]
        M[:, :, 1] = c * H[:, :, 1] - s * H[:, :, 0]
        M[:, :, 2] = poses[:, :1] * H[:, :, 0] + poses[:, 1:2] * H[:, :, 1] + H[:, :, 2]
        q = M @ (self._V[0] if len(self._V) == 1 else self._V[owner])  # (N, 3, V)
        out = np.empty((len(poses), q.shape[2], 2))
        np.divide(q[:, 0], q[:, 2], out=out[..., 0])
        np.divide(q[:, 1], q[:, 2], out=out[..., 1])
        return out

    def __call__(self, poses: np.ndarray, coarse: int = 1, owner=None) -> np.ndarray:
        """poses (N, 3) -> (N,) scores; ``coarse``: that many times fewer samples per edge (a
        cheaper look at many poses); ``owner`` (N,): each pose's window (default: the first)."""
        owner = np.zeros(len(poses), np.intp) if owner is None else np.asarray(owner, np.intp)
        p = self.polygons(poses, owner).astype(np.float32)
        d = p[:, self._next] - p  # (N, V, 2)
        edge, t, wt = self._table(coarse)
        if len(edge) == 1:
            e, t, wt = edge[0], t[0], wt[0]
            px, py, dx, dy = p[:, e, 0], p[:, e, 1], d[:, e, 0], d[:, e, 1]  # (N, M)
        else:
            t, wt = t[owner], wt[owner]
            # Each sample's corner and edge, read from the flat (N * V, 2) arrays.
            j = edge[owner] + (np.arange(len(poses)) * p.shape[1])[:, None]
            pf, df = p.reshape(-1, 2), d.reshape(-1, 2)
            px, py, dx, dy = pf[j, 0], pf[j, 1], df[j, 0], df[j, 1]
        x = px + t * dx
        y = py + t * dy
        w = self._w[owner][:, None]
        # Clamped into the window (the bare ufuncs: np.clip's wrapper costs more than the work).
        np.minimum(np.maximum(x, 0.0, out=x), (w - 1e-3).astype(np.float32), out=x)
        np.minimum(np.maximum(y, 0.0, out=y), (self._h[owner][:, None] - 1 - 1e-3).astype(np.float32), out=y)
        ix, iy = x.astype(np.intp), y.astype(np.intp)
        x -= ix
        y -= iy
        k = self._off[owner][:, None] + iy * (w + 1) + ix
        C = self._C
        c0 = C[k]
        top = c0 + x * (C[k + 1] - c0)
        k += w + 1
        c0 = C[k]
        top += y * (c0 + x * (C[k + 1] - c0) - top)
        s = np.einsum("nm,nm->n", top, dy * wt)
        # The same line integral of x gives the polygon's signed area: its sign is the winding.
        area = np.einsum("nv,nv->n", p[..., 0] + 0.5 * d[..., 0], d[..., 1])
        return np.where(area < 0, -s, s)


def pixels_inside(polygon: np.ndarray, shape: tuple[int, int], origin: tuple[int, int]) -> np.ndarray:
    """Which pixel centres of a window (``shape`` (h, w), its pixel (0, 0) at image pixel
    ``origin``) lie inside a convex polygon (V, 2) in image pixel coordinates."""
    h, w = shape
    u = np.arange(w)[None, :] + origin[0]
    v = np.arange(h)[:, None] + origin[1]
    return convex_inside_distance(polygon, u, v) >= 0


# A stencil of 19 poses: the centre, a step either way along each coordinate, and a step
# along each pair of coordinates at once (offsets -1, 0, 1 with at most two non-zero), and
# the least-squares fit of a quadratic in three variables to scores on it: coefficients of
# 1, x, y, t, x^2, y^2, t^2, xy, xt, yt.
_CUBE = (
    np.array(np.meshgrid([-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0], indexing="ij"))
    .reshape(3, -1)
    .T
)
_STENCIL = _CUBE[np.count_nonzero(_CUBE, axis=1) <= 2]
_x, _y, _t = _STENCIL.T
_QUADRATIC = np.linalg.pinv(
    np.column_stack(
        [np.ones(len(_STENCIL)), _x, _y, _t, _x * _x, _y * _y, _t * _t, _x * _y, _x * _t, _y * _t]
    )
)


def quadratic_search(score, starts: np.ndarray, step, tol: float, max_rounds: int = 12):
    """Maximises ``score`` (poses (N, 3), owner= (N,) -> (N,)) for F fits at once, near each
    of their starts (``starts`` (F, S, 3); or (S, 3) for one fit, owner 0). Each round scores
    a stencil of ``step`` around each pose (`_STENCIL`) and fits a quadratic to it. Where the
    quadratic has a maximum, the pose moves there (at most one step along each coordinate),
    else to the stencil's best pose. A fit's step is halved after a round whose move stayed
    inside the stencil, and kept while the pose is still travelling; its search ends when its
    first step is below ``tol`` (or after ``max_rounds``). After the first round each fit goes
    on from its start whose stencil scored best. Returns the best poses scored (F, 3) and
    their scores (F,); for one fit, one pose and its score."""
    single = np.ndim(starts) == 2
    P = np.array(starts, float)[None] if single else np.array(starts, float)
    F, S = P.shape[:2]
    n = len(_STENCIL)
    h = np.tile(np.asarray(step, float), (F, 1))
    best_p, best_s = P[:, 0].copy(), np.full(F, -np.inf)
    fits = np.arange(F)
    # Round 0: every start of every fit.
    poses = P[:, :, None, :] + _STENCIL[None, None] * h[:, None, None, :]  # (F, S, n, 3)
    s = score(poses.reshape(-1, 3), owner=np.repeat(fits, S * n)).reshape(F, S, n)
    k = np.argmax(s.max(axis=2), axis=1)  # each fit's best start
    p, s = P[fits, k], s[fits, k]  # (F, 3), (F, n)
    live = fits
    for r in range(max_rounds):
        if r > 0:
            live = fits[h[:, 0] >= tol]
            if len(live) == 0:
                break
            poses = p[live, None, :] + _STENCIL[None] * h[live, None, :]  # (L, n, 3)
            s = score(poses.reshape(-1, 3), owner=np.repeat(live, n)).reshape(len(live), n)
        else:
            poses = p[:, None, :] + _STENCIL[None] * h[:, None, :]
        j = np.argmax(s, axis=1)
        top = s[np.arange(len(live)), j]
        up = top > best_s[live]
        best_p[live[up]], best_s[live[up]] = poses[np.flatnonzero(up), j[up]], top[up]
        c = s @ _QUADRATIC.T  # (L, 10)
        H = np.empty((len(live), 3, 3))
        H[:, 0, 0], H[:, 1, 1], H[:, 2, 2] = 2 * c[:, 4], 2 * c[:, 5], 2 * c[:, 6]
        H[:, 0, 1] = H[:, 1, 0] = c[:, 7]
        H[:, 0, 2] = H[:, 2, 0] = c[:, 8]
        H[:, 1, 2] = H[:, 2, 1] = c[:, 9]
        move = _STENCIL[j].copy()
        peak = np.all(np.linalg.eigvalsh(H) < 0, axis=1)  # a maximum: Newton's step, clipped
        if peak.any():
            move[peak] = np.clip(np.linalg.solve(H[peak], -c[peak, 1:4, None])[..., 0], -1.0, 1.0)
        p[live] += move * h[live]
        arrived = np.max(np.abs(move), axis=1) < 0.999  # arrived: look closer
        h[live[arrived]] /= 2
    s = score(p, owner=fits)
    up = s > best_s
    best_p[up], best_s[up] = p[up], s[up]
    if single:
        return best_p[0], float(best_s[0])
    return best_p, best_s
