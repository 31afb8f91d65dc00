"""Object poses from an overhead RGB-D image: what a real camera gives, never ground truth.

1. Back-project every depth pixel to a point in the table frame (camera pose and intrinsics).
2. Points more than `min_height` above the table are object points; each takes the library
   shape whose colour chromaticity (rgb / max channel, which shading does not change) is
   nearest. Table points are negatives.
3. Object points of one shape are split into connected clusters; a cluster holds
   round(visible area / shape area) instances (touching objects included).
4. Each instance is fitted by maximising a smooth score: points of its shape inside the
   polygon minus negatives (table, other shapes, instances already fitted) inside, from
   several starts (k-means centres; angles over the shape's symmetry), refined by a shrinking
   coordinate search. Fitted points then count as negatives for the next instance.

Object points no fitted polygon explains are reported as unrecognised blobs, each with its
outline and top height (``scene.meta["unrecognised"]``).

`Perceiver` runs the steps above. Pure numpy and shapely: no Drake import (the Perception LeafSystem wraps this).
"""

import math
from dataclasses import dataclass, field

import numpy as np

from mog_drake.errors import MogError
from mog_drake.geometry.polygon import polygon_centroid, transform
from mog_drake.perception.fitting import (
    FIT_MARGIN,
    NEGATIVE_WEIGHT,
    PointIndex,
    _clusters,
    _outline,
    _seedings,
    _signed_distance,
    _soft_inside,
    separate_overlaps,
    symmetry_order,
)
from mog_drake.perception.pointcloud import backproject, chromaticity
from mog_drake.scenes import Scene, SceneObject, ShapeLibrary, default_library


@dataclass
class PerceptionConfig:
    min_height: float = 0.004  # m above the table: an object point
    max_height: float = 0.060  # m: anything higher (the arm, the bin walls) is ignored
    softness: float = 0.0004  # m, width of the score's edge
    min_fraction: float = 0.35  # a cluster smaller than this share of a shape is noise
    unknown_area: float = 60e-6  # m^2: unexplained object points covering more are an unrecognised blob
    wall_margin: float = 0.004  # m around a fitted polygon where side-wall points are explained
    shapes: list[str] = field(default_factory=list)  # shapes to look for (default: every library shape)
    # A cluster holding three or more instances of one shape (touching, one colour and height)
    # is split from this many k-means seedings (two instances: from median splits along 6
    # directions, see _seedings); the split whose fits explain most of its points, less their
    # spill onto the table, is kept. One seeding split two touching thin bars wrongly on some
    # pixel grids.
    separation_tries: int = 5


def within_reach(x: float, y: float, reach) -> bool:
    """Whether (x, y) lies in the disc ``reach`` = (cx, cy, radius); any point for None."""
    if reach is None:
        return True
    cx, cy, r = reach
    return math.hypot(x - cx, y - cy) <= r


def _inside(P: np.ndarray, rect) -> np.ndarray:
    """Which points of P (..., 3) lie strictly inside rect (xmin, xmax, ymin, ymax) in x, y."""
    x0, x1, y0, y1 = rect
    return (P[..., 0] > x0) & (P[..., 0] < x1) & (P[..., 1] > y0) & (P[..., 1] < y1)


class Perceiver:
    """Turns (rgb, depth, camera) into a perceived Scene."""

    def __init__(
        self,
        library: ShapeLibrary | None = None,
        config: PerceptionConfig | None = None,
        *,
        table,
        ignore=(),
        reach=None,
    ):
        """``table``: the perceived table (xmin, xmax, ymin, ymax; the scenario's ``table``).
        ``ignore``: rectangles (xmin, xmax, ymin, ymax) of the table where no object is
        looked for: fixtures standing on it, such as the bin, whose walls the camera sees.
        ``reach``: a disc (x, y, radius), the arm's reach; an object (or unrecognised blob)
        whose centre lies outside it is not reported (counted in ``meta["beyond_reach"]``):
        the robot could not pick it, and planning for it would only fail."""
        self.library = library or default_library()
        self.config = config or PerceptionConfig()
        self.table = table
        self.ignore = [tuple(float(v) for v in r) for r in ignore]
        for r in self.ignore:
            if len(r) != 4 or not (r[0] < r[1] and r[2] < r[3]):
                raise MogError(f"an ignored region must be (xmin, xmax, ymin, ymax) with min < max, got {r}")
        self.reach = None if reach is None else tuple(float(v) for v in reach)
        if self.reach is not None and (len(self.reach) != 3 or not self.reach[2] > 0):
            raise MogError(f"reach must be (x, y, radius) with radius > 0, got {reach}")
        names = list(self.config.shapes) or list(self.library.shapes)
        # Toppled bars too: the same colour, a different top height and footprint.
        names += [v for v in self.library.resting_variants() if self.library.base_shape(v) in names]
        self.names = names
        self.chroma = np.array([chromaticity(np.array(self.library[n].color[:3])) for n in names])
        # Shapes of one colour share a colour class (the first of them); height tells them apart.
        self.colour_class = np.array(
            [
                next(j for j in range(len(names)) if np.allclose(self.chroma[j], self.chroma[k]))
                for k in range(len(names))
            ]
        )
        self.sym = {n: symmetry_order(self.library[n].vertices) for n in names}

    def perceive(
        self, rgb: np.ndarray, depth: np.ndarray, X_WC: np.ndarray, intrinsics, seed: int = 0
    ) -> Scene:
        """rgb (H, W, 3 or 4) uint8, depth (H, W) m, X_WC 4x4 camera pose, intrinsics (fx, fy, cx, cy)."""
        cfg = self.config
        fx, fy, cx, cy = intrinsics
        P = backproject(np.asarray(depth, float).reshape(rgb.shape[:2]), np.asarray(X_WC), fx, fy, cx, cy)
        ok = np.isfinite(P[..., 2]) & _inside(P, self.table)
        for r in self.ignore:
            ok &= ~_inside(P, r)
        obj = ok & (P[..., 2] > cfg.min_height) & (P[..., 2] < cfg.max_height)
        table = ok & (P[..., 2] <= cfg.min_height)
        # Footprint of one pixel on a plane facing the camera at its depth: its weight in areas.
        area_px = (np.asarray(depth, float).reshape(rgb.shape[:2]) ** 2) / (fx * fy)
        ch = chromaticity(rgb[..., :3])[obj]
        cls = self.colour_class[np.argmin(((ch[:, None, :] - self.chroma[None]) ** 2).sum(-1), axis=1)]
        pts, z, w = P[obj][:, :2], P[obj][:, 2], area_px[obj]
        negatives = P[table][:, :2]
        negative_index = PointIndex(negatives)
        rng = np.random.default_rng(seed)
        found: list[SceneObject] = []
        explained = np.zeros(len(pts), dtype=bool)
        # Large shapes first: their fits then mask their pixels for the smaller ones.
        order = sorted(range(len(self.names)), key=lambda k: -self.library[self.names[k]].area)
        for k in order:
            name = self.names[k]
            shape = self.library[name]
            colour = cls == self.colour_class[k]
            top = np.abs(z - shape.height) < 0.004
            mine = np.flatnonzero(colour & top)
            others = PointIndex(pts[~colour]) if len(mine) else None
            for members in _clusters(pts[mine], 0.0025):
                idx = mine[members]
                n_est = int(round(w[idx].sum() / shape.area))
                if w[idx].sum() < cfg.min_fraction * shape.area:
                    continue
                n_est = max(n_est, 1)
                best = None  # (score of the split, explained mask, objects)
                for seeds in _seedings(pts[idx], min(n_est, len(idx)), cfg.separation_tries, rng):
                    mask, objs, spill = explained.copy(), [], 0
                    for centre in seeds:
                        pose = self._fit(shape, name, pts, idx, mask, negative_index, others, centre)
                        if pose is None:
                            continue
                        poly = transform(shape.vertices, *pose)
                        mask |= (_soft_inside(pts, poly, cfg.softness) > 0.5) & colour
                        if n_est > 1:  # one try alone needs no score
                            near = negative_index.within(np.asarray(pose[:2]), shape.radius + FIT_MARGIN)
                            spill += int((_soft_inside(near, poly, cfg.softness) > 0.5).sum())
                        objs.append(SceneObject(name, *pose))
                    # Points of the cluster explained, less each table point under a fit as
                    # _fit weighs it: two fits lying across two bars side by side explain
                    # most of them but spill onto the table.
                    score = int(mask[idx].sum()) - NEGATIVE_WEIGHT * spill
                    if best is None or score > best[0]:
                        best = (score, mask, objs)
                explained = best[1]
                found.extend(best[2])
        # Object points no fitted polygon explains (a prism knocked onto its side, say, or
        # something not in the library): reported, so nobody calls such a table clear.
        covered = np.zeros(len(pts), dtype=bool)
        for o in found:
            poly = transform(self.library[o.shape].vertices, o.x, o.y, o.theta)
            covered |= _signed_distance(pts, poly) < cfg.wall_margin  # tops and the side walls around them
        rest = np.flatnonzero(~covered)
        unknown = [rest[c] for c in _clusters(pts[rest], 0.0025) if w[rest[c]].sum() > cfg.unknown_area]
        found, moved = separate_overlaps(found, self.library)
        n_seen = len(found) + len(unknown)
        found = [o for o in found if within_reach(o.x, o.y, self.reach)]
        unknown = [idx for idx in unknown if within_reach(*pts[idx].mean(axis=0), self.reach)]
        scene = Scene(found, self.library, table=tuple(self.table))
        scene.meta["beyond_reach"] = n_seen - len(found) - len(unknown)
        scene.meta["unrecognised_blobs"] = len(unknown)
        # Each blob's outline seen from above (the convex hull of its points, simplified to
        # 1 mm) and the height of its top: enough to plan a grasp of it as a prism.
        scene.meta["unrecognised"] = [
            {"vertices": outline.round(5).tolist(), "top": round(float(np.percentile(z[idx], 95)), 5)}
            for idx in unknown
            if (outline := _outline(pts[idx])) is not None
        ]
        scene.meta["overlap_corrections"] = moved
        return scene

    def _fit(self, shape, name, pts, idx, explained, negatives, others, centre):
        cfg = self.config
        r = shape.radius + FIT_MARGIN

        def near(a):
            return a[np.linalg.norm(a - centre, axis=1) < r]

        pos = near(pts[idx][~explained[idx]])
        if len(pos) < 5:
            return None
        neg = np.concatenate([negatives.within(centre, r), others.within(centre, r), near(pts[explained])])
        allp = np.concatenate([pos, neg])
        weight = np.concatenate([np.ones(len(pos)), -NEGATIVE_WEIGHT * np.ones(len(neg))])
        c_body = polygon_centroid(shape.vertices)
        v0 = shape.vertices
        e0 = np.roll(v0, -1, axis=0) - v0
        n0 = np.stack([e0[:, 1], -e0[:, 0]], axis=1) / np.linalg.norm(e0, axis=1, keepdims=True)
        px, py = allp[:, 0], allp[:, 1]

        def scores(poses):
            # poses (N, 3) -> (N,) smooth score: inside points of the shape less weighted negatives.
            c, s_ = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
            # Outward edge normals turn with the pose; offsets are normal . vertex.
            nx = c * n0[None, :, 0] - s_ * n0[None, :, 1]
            ny = s_ * n0[None, :, 0] + c * n0[None, :, 1]
            vx = c * v0[None, :, 0] - s_ * v0[None, :, 1] + poses[:, :1]
            vy = s_ * v0[None, :, 0] + c * v0[None, :, 1] + poses[:, 1:2]
            off = nx * vx + ny * vy  # (N, V)
            # Signed distance to the polygon: the largest edge distance, one edge at a time
            # (no (N, P, V) temporary: the same numbers at a fraction of the memory traffic).
            sd = px[None, :] * nx[:, :1] + py[None, :] * ny[:, :1] - off[:, :1]
            for e in range(1, nx.shape[1]):
                np.maximum(
                    sd,
                    px[None, :] * nx[:, e : e + 1] + py[None, :] * ny[:, e : e + 1] - off[:, e : e + 1],
                    out=sd,
                )
            np.divide(sd, cfg.softness, out=sd)
            np.clip(sd, -50, 50, out=sd)
            np.exp(sd, out=sd)
            sd += 1.0
            np.reciprocal(sd, out=sd)
            return sd @ weight

        period = 2 * math.pi / self.sym[name]
        ths = np.arange(0.0, period, math.radians(5.0))
        offs = np.stack([transform(c_body[None], 0.0, 0.0, th)[0] for th in ths])
        starts = np.column_stack([centre[0] - offs[:, 0], centre[1] - offs[:, 1], ths])
        s0 = scores(starts)
        # Refine the best few distinct peaks of the (circular) angle sweep: the best start is
        # not always in the right basin (a trapezoid seen from its centroid, say).
        peaks = [k for k in range(len(s0)) if s0[k] >= s0[k - 1] and s0[k] >= s0[(k + 1) % len(s0)]]
        best, best_s = None, -np.inf
        for k in sorted(peaks, key=lambda k: -s0[k])[:3]:
            p, ps = starts[k].copy(), s0[k]
            step = np.array([0.002, 0.002, math.radians(3.0)])
            while step[0] > 1e-4:
                moves = np.concatenate([p + np.diag(step), p - np.diag(step)])
                ms = scores(moves)
                j = int(np.argmax(ms))
                if ms[j] > ps:
                    p, ps = moves[j], ms[j]
                else:
                    step /= 2
            if ps > best_s:
                best, best_s = p, ps
        best[2] = math.remainder(best[2], 2 * math.pi)
        return tuple(float(v) for v in best)
