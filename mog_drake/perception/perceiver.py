"""Object poses from an overhead RGB-D image: what a real camera gives, never ground truth.

1. Back-project every depth pixel to a point in the table frame (camera pose and intrinsics).
2. Pixels more than `min_height` above the table are object pixels; each takes the library
   shape whose colour chromaticity (rgb / max channel, which shading does not change) is
   nearest.
3. For each shape, the object pixels of its colour at its top height form connected
   components in the image; a component holds round(visible area / shape area) instances
   (touching objects included).
4. Each instance is fitted where the shape's top face, projected into the image at its
   height, covers most evidence: +1 for each pixel of the component, -NEGATIVE_WEIGHT for
   each pixel that rules the top face out there (a surface lower than the top, such as the
   table or a side wall; another colour at the top's height; an instance already fitted),
   0 for a pixel above the top (a taller neighbour hiding part of it says nothing). The
   score of a pose is a line integral around the projected polygon (`PolygonScore`): its cost
   grows with the polygon's perimeter, not its area. Starts: the component's centre (k-means
   centres for several instances) at angles over the shape's symmetry; the best few are
   refined together by a shrinking coordinate search. Fitted pixels then count against the
   next instance.

Object pixels no fitted polygon explains are reported as unrecognised blobs, each with its
outline and top height (``scene.meta["unrecognised"]``).

`Perceiver` runs the steps above. Pure numpy, scipy.ndimage and shapely: no Drake import (the
Perception LeafSystem wraps this).
"""

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from mog_drake.errors import MogError
from mog_drake.geometry.polygon import polygon_centroid, transform
from mog_drake.perception.fitting import (
    FIT_MARGIN,
    NEGATIVE_WEIGHT,
    PolygonScore,
    _outline,
    _seedings,
    components,
    near_polygon,
    pixels_inside,
    quadratic_search,
    separate_overlaps,
    symmetry_order,
)
from mog_drake.perception.pointcloud import Pinhole, backproject, chromaticity
from mog_drake.scenes import Scene, SceneObject, ShapeLibrary, default_library


@dataclass
class PerceptionConfig:
    min_height: float = 0.004  # m above the table: an object point
    max_height: float = 0.060  # m: anything higher (the arm, the bin walls) is ignored
    top_band: float = 0.004  # m: a pixel within this of a shape's top height is at its top
    min_fraction: float = 0.35  # a component smaller than this share of a shape is noise
    unknown_area: float = 60e-6  # m^2: unexplained object pixels covering more are an unrecognised blob
    wall_margin: float = 0.004  # m around a fitted polygon where side-wall pixels are explained
    shapes: list[str] = field(default_factory=list)  # shapes to look for (default: every library shape)
    # A component holding several instances of one shape (touching, one colour and height) is
    # split from this many seedings: k-means centres for three or more instances, median
    # splits along separation_tries + 1 directions for two (see _seedings). Its instances are
    # fitted best first; the split whose fits explain most of its pixels, less their spill
    # onto lower surfaces, is kept, and one whose every fit is clean ends the search.
    separation_tries: int = 2
    # m: fits of three or more instances start from centres this far around each seed (a
    # k-means centre can fall between two bars lying side by side).
    split_spread: float = 0.006
    refits: int = 1  # passes fitting each instance of a split again, the others' pixels explained


def within_reach(x: float, y: float, reach) -> bool:
    """Whether (x, y) lies in the disc ``reach`` = (cx, cy, radius); any point for None."""
    if reach is None:
        return True
    cx, cy, r = reach
    return math.hypot(x - cx, y - cy) <= r


def _flat(depth: np.ndarray, step: float) -> np.ndarray:
    """Pixels whose depth differs from each 4-neighbour's by less than ``step`` (tops and the
    table, not side walls nor edges)."""
    out = np.isfinite(depth)
    for axis in (0, 1):
        d = np.abs(np.diff(depth, axis=axis)) < step  # nan compares False
        lo = [slice(None)] * 2
        hi = [slice(None)] * 2
        lo[axis], hi[axis] = slice(0, -1), slice(1, None)
        out[tuple(lo)] &= d
        out[tuple(hi)] &= d
    return out


def _inside(P: np.ndarray, rect) -> np.ndarray:
    """Which points of P (..., 3) lie strictly inside rect (xmin, xmax, ymin, ymax) in x, y."""
    x0, x1, y0, y1 = rect
    return (P[..., 0] > x0) & (P[..., 0] < x1) & (P[..., 1] > y0) & (P[..., 1] < y1)


# The fit's search: its first steps (m, m, rad), and the step (m) it stops at.
FIT_STEP = (0.002, 0.002, math.radians(3.0))
FIT_TOL = 3e-4
# Starting angles: every 5 deg over the shape's symmetry period; the best few are refined.
START_ANGLE_STEP = math.radians(5.0)
REFINED_STARTS = 3
PEAK_SHARE = 0.7  # a peak scoring less than this share of the best is not refined
SPREAD_GRID = 5  # centres per axis of a split's start grid
COARSE = 3  # starts are scored with this many times fewer samples per edge
EDGE_SAMPLES = 4  # samples of an edge at the least
SAMPLES_PER_PIXEL = 1.0  # samples of an edge per pixel of its length
# A clean fit's score falls short of its area (pixels) by at most this per pixel of its
# perimeter. Right fits lose about 0.3 (outline pixels partly covered: the part of a pixel
# outside the top counts against the fit); a fit across two instances loses 2.5 per pixel of
# table under it, 0.7 or more per pixel of perimeter.
CLEAN_EDGE = 0.6


@dataclass
class _Window:
    """Where one instance is fitted: its score over a window of the image (rows, cols), the
    window's origin pixel, which of its pixels are lower than the shape's top, and the seed."""

    score: PolygonScore
    rows: slice
    cols: slice
    origin: tuple
    lower: np.ndarray
    centre: np.ndarray
    k: int = 0  # the shape (index into Perceiver.names)


@dataclass
class _Fit:
    """One fitted instance: its pose, the window of the image it was fitted in, which pixels
    of the window lie inside it and which are lower than its top, its score, and whether it
    is clean: its score falls short of the pixels it covers by no more than its partly
    covered outline pixels can take (`CLEAN_EDGE` per pixel of perimeter), so it covers its
    own instance's pixels and nothing that rules it out."""

    pose: tuple
    window: tuple
    inside: np.ndarray
    lower: np.ndarray
    score: float
    clean: bool
    k: int = 0  # the shape (index into Perceiver.names)

    @property
    def spill(self) -> int:
        return int((self.inside & self.lower).sum())


def _explain(before: np.ndarray, fits: list[_Fit], colour: np.ndarray) -> np.ndarray:
    """``before`` with the pixels of ``colour`` inside each fit marked explained (a copy)."""
    out = before.copy()
    for f in fits:
        out[f.window] |= f.inside & colour[f.window]
    return out


def _clean_apart(fits: list[_Fit], im) -> bool:
    """Whether every fit is clean and no pixel lies inside two of them."""
    if not all(f.clean for f in fits):
        return False
    count = np.zeros(im.shape, dtype=np.uint8)
    for f in fits:
        count[f.window] += f.inside
    return int(count.max()) <= 1


_CORNERS = ((-1, -1), (1, -1), (1, 1), (-1, 1))


class _Image:
    """What one perceive call knows of the image: per-pixel points (P, nan where not on the
    perceived table), heights, colour classes (-1 off the object pixels), which pixels are
    explained by a fit, and the camera."""

    def __init__(self, P, z, cls, cam):
        self.P, self.z, self.cls, self.cam = P, z, cls, cam
        self.shape = z.shape
        self.xy = P[..., :2].reshape(-1, 2)
        self.explained = np.zeros(z.shape, dtype=bool)
        self.samples: dict[int, tuple] = {}  # shape -> samples per edge (Perceiver._edge_samples)

    def window(self, centre, r: float, height: float, pad: int = 3):
        """Slices (rows, cols) of the pixels that can see the disc (centre, r) at ``height``."""
        cx, cy = float(centre[0]), float(centre[1])
        uv = [self.cam.project_point(cx + sx * r, cy + sy * r, height) for sx, sy in _CORNERS]
        us, vs = [a for a, _ in uv], [b for _, b in uv]
        h, w = self.shape
        u0 = min(max(math.floor(min(us)) - pad, 0), w - 2)
        u1 = min(max(math.ceil(max(us)) + pad + 1, u0 + 2), w)
        v0 = min(max(math.floor(min(vs)) - pad, 0), h - 2)
        v1 = min(max(math.ceil(max(vs)) + pad + 1, v0 + 2), h)
        return slice(v0, v1), slice(u0, u1)


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
        self.area = [self.library[n].area for n in names]

    def changed_pixels(
        self,
        before: np.ndarray,
        after: np.ndarray,
        X_WC,
        intrinsics,
        tol: float = 0.004,
        settle_px: int = 2,
        still: bool = False,
    ) -> int:
        """How many pixels of the perceived table (its rectangle less the ignored regions, as
        seen in ``after``) tell that the table changed between two depth images: their depth
        moved by more than ``tol`` m, or an object (``min_height`` to ``max_height`` above
        the table) is now where ``before`` saw something higher than any object (the arm
        over the table) or nothing; in regions at least ``settle_px`` pixels wide every way
        (an object moved by about that many pixels, 3.7 mm at the defaults, or more). A cheap
        check, not a perception: no fitting. ``still``: whether what both images see of the
        table is at rest (two frames a moment apart while the arm may still be in view):
        pixels where either image sees the arm count for nothing."""
        cfg = self.config
        X_WC = np.asarray(X_WC, float)
        after = np.asarray(after, np.float32)
        before = np.asarray(before, np.float32).reshape(after.shape)
        Pa = backproject(after, X_WC, *intrinsics)
        region = np.isfinite(Pa[..., 2]) & _inside(Pa, self.table)
        for r in self.ignore:
            region &= ~_inside(Pa, r)
        zb = backproject(before, X_WC, *intrinsics)[..., 2]
        hidden = ~(zb < cfg.max_height)  # the arm, or no depth: nothing known there
        za = Pa[..., 2]
        if still:
            hidden |= ~(za < cfg.max_height)
        # Side walls count for nothing: seen edge-on, their pixels change depth with a tilt of
        # a degree or a rocking object (on rendered tables, the same wall moved by a pixel or
        # two with its object at rest); tops and the table change only when something moves.
        flat = _flat(before, tol) & _flat(after, tol)
        moved = region & ~hidden & flat & (np.abs(before - after) > tol)
        appeared = region & hidden & (za > cfg.min_height) & (za < cfg.max_height) & (not still)
        # Strips narrower than `settle_px` pixels go: an object that slid a fraction of a
        # millimetre shifts its outline by a pixel, which is no change worth a new plan.
        changed = moved | appeared
        if settle_px:
            changed = ndimage.binary_opening(changed, structure=np.ones((settle_px, settle_px), bool))
        return int(changed.sum())

    def perceive(
        self, rgb: np.ndarray, depth: np.ndarray, X_WC: np.ndarray, intrinsics, seed: int = 0
    ) -> Scene:
        """rgb (H, W, 3 or 4) uint8, depth (H, W) m, X_WC 4x4 camera pose, intrinsics (fx, fy, cx, cy)."""
        cfg = self.config
        fx, fy, cx, cy = intrinsics
        depth = np.asarray(depth).reshape(rgb.shape[:2])
        if depth.dtype != np.float32:
            depth = depth.astype(np.float64)
        P = backproject(depth, np.asarray(X_WC, float), fx, fy, cx, cy)
        ok = np.isfinite(P[..., 2]) & _inside(P, self.table)
        for r in self.ignore:
            ok &= ~_inside(P, r)
        P[~ok] = np.nan
        z = P[..., 2]
        obj = ok & (z > cfg.min_height) & (z < cfg.max_height)
        # Footprint of one pixel on a plane facing the camera at its depth: its weight in areas.
        area_px = np.where(obj, depth**2 / (fx * fy), 0.0)
        # Nearest chromaticity: argmin |c - k|^2 = argmin |k|^2 - 2 c.k. Written out per
        # channel, not as a matrix product: a product this tall is one OpenBLAS threads, and
        # its worker then spins on the other core for about 0.1 s after it (measured: twice
        # the CPU time of the wall time per image), a core the simulator and the planner need.
        obj_px = np.flatnonzero(obj)
        ch = chromaticity(rgb[..., :3].reshape(-1, 3)[obj_px])
        K = self.chroma
        dots = ch[:, 0, None] * K[:, 0] + ch[:, 1, None] * K[:, 1] + ch[:, 2, None] * K[:, 2]
        obj_cls = self.colour_class[np.argmin((K**2).sum(-1) - 2 * dots, axis=1)]
        obj_z = z.ravel()[obj_px]
        cls = np.full(z.shape, -1, dtype=np.int32)
        cls.ravel()[obj_px] = obj_cls
        im = _Image(P, z, cls, Pinhole(X_WC, intrinsics))
        rng = np.random.default_rng(seed)
        found: list[SceneObject] = []
        # Large shapes first: their fits then mask their pixels for the smaller ones. The
        # lone instances of shapes that cannot take each other's pixels (another colour, or
        # a top at another height) are fitted in one batch, the touching instances of each
        # shape after them; a shape that can take a pending one's pixels waits for its fits.
        order = sorted(range(len(self.names)), key=lambda k: -self.area[k])
        found_by: dict[int, list[SceneObject]] = {k: [] for k in order}
        pending: list[tuple] = []  # (k, labels, colour mask, several) whose lone windows wait
        wins: list[_Window] = []

        def flush():
            colours = {k: colour for k, _, colour, _ in pending}
            for f in self._fit_windows(im, wins) if wins else ():
                im.explained[f.window] |= f.inside & colours[f.k][f.window]
                found_by[f.k].append(SceneObject(self.names[f.k], *f.pose))
            for k, labels, colour, several in pending:
                for label, idx, n_est in several:
                    found_by[k].extend(self._split(k, im, labels, label, idx, n_est, colour, rng))
            pending.clear()
            wins.clear()

        for k in order:
            if any(self._interact(k, j) for j, *_ in pending):
                flush()
            shape = self.library[self.names[k]]
            area = self.area[k]
            mine = obj_px[(obj_cls == self.colour_class[k]) & (np.abs(obj_z - shape.height) < cfg.top_band)]
            labels, members = components(mine, z.shape)
            if not members:
                continue
            colour = cls == self.colour_class[k]
            lone, several = [], []
            for label, idx in enumerate(members, start=1):
                visible = float(area_px.ravel()[idx].sum())
                if visible >= cfg.min_fraction * area:
                    n_est = max(int(round(visible / area)), 1)
                    (lone if n_est == 1 else several).append((label, idx, n_est))
            lone_windows = (
                self._window(k, im, labels, label, im.xy[idx].mean(axis=0)) for label, idx, _ in lone
            )
            wins.extend(w for w in lone_windows if w is not None)
            pending.append((k, labels, colour, several))
        flush()
        found = [o for k in order for o in found_by[k]]
        # Object pixels no fitted polygon explains (a prism knocked onto its side, say, or
        # something not in the library): reported, so nobody calls such a table clear.
        covered = np.zeros(z.shape, dtype=bool)
        for o in found:
            shape = self.library[o.shape]
            rows, cols = im.window((o.x, o.y), shape.radius + cfg.wall_margin, 0.0)
            poly = transform(shape.vertices, o.x, o.y, o.theta)
            # Its top and its side walls:
            covered[rows, cols] |= near_polygon(P[rows, cols, 0], P[rows, cols, 1], poly, cfg.wall_margin)
        _, blobs = components(np.flatnonzero(obj & ~covered), z.shape)
        unknown = [idx for idx in blobs if area_px.ravel()[idx].sum() > cfg.unknown_area]
        found, moved = separate_overlaps(found, self.library)
        n_seen = len(found) + len(unknown)
        found = [o for o in found if within_reach(o.x, o.y, self.reach)]
        unknown = [idx for idx in unknown if within_reach(*im.xy[idx].mean(axis=0), self.reach)]
        scene = Scene(found, self.library, table=tuple(self.table))
        scene.meta["beyond_reach"] = n_seen - len(found) - len(unknown)
        scene.meta["unrecognised_blobs"] = len(unknown)
        # Each blob's outline seen from above (the convex hull of its points, simplified to
        # 1 mm) and the height of its top: enough to plan a grasp of it as a prism.
        zf = z.ravel()
        scene.meta["unrecognised"] = [
            {"vertices": outline.round(5).tolist(), "top": round(float(np.percentile(zf[idx], 95)), 5)}
            for idx in unknown
            if (outline := _outline(im.xy[idx])) is not None
        ]
        scene.meta["overlap_corrections"] = moved
        return scene

    def _edge_samples(self, k: int, im: _Image) -> tuple:
        """Samples of each edge of shape ``k``'s top face: about one per pixel of its length
        as seen at the table's centre (at least EDGE_SAMPLES), the same for every window of
        the shape, so that its windows share one table of samples."""
        if k not in im.samples:
            shape = self.library[self.names[k]]
            cx, cy = (self.table[0] + self.table[1]) / 2, (self.table[2] + self.table[3]) / 2
            uv = im.cam.project(transform(shape.vertices, cx, cy, 0.0), shape.height)
            lengths = np.linalg.norm(np.roll(uv, -1, axis=0) - uv, axis=1)
            im.samples[k] = tuple(max(int(math.ceil(n * SAMPLES_PER_PIXEL)), EDGE_SAMPLES) for n in lengths)
        return im.samples[k]

    def _interact(self, k: int, j: int) -> bool:
        """Whether shapes k and j can take each other's pixels: one colour, tops within two
        height bands."""
        return (
            self.colour_class[k] == self.colour_class[j]
            and abs(self.library[self.names[k]].height - self.library[self.names[j]].height)
            < 2 * self.config.top_band
        )

    def _split(self, k: int, im: _Image, labels, label: int, idx, n_est: int, colour, rng) -> list:
        """Fits ``n_est`` touching instances of shape ``k`` to component ``label`` (its flat
        pixel indices ``idx``): the objects of the best split, their pixels left explained."""
        cfg = self.config
        name = self.names[k]
        shape = self.library[name]
        pts = im.xy[idx]
        best = None  # (score of the split, explained mask, objects)
        for seeds in _seedings(pts, min(n_est, len(idx)), cfg.separation_tries, rng):
            before = im.explained
            fits: list[_Fit] = []
            # Best first: every seed left is fitted, and the fit that explains most
            # (an instance standing clear of the others) is kept; its pixels then
            # count against the next ones.
            # (All the seeds left are fitted in one batch: one search, not one each.)
            left = list(seeds)
            spread = cfg.split_spread if len(seeds) > 2 else 0.0
            while left:
                im.explained = _explain(before, fits, colour)
                tries = self._fit_many(k, im, labels, label, left, spread=spread)
                if not tries:
                    break
                # Fitted together on the same evidence, every instance clean and none
                # overlapping another: each covers its own pixels, so fitting them one
                # by one would only fit clean instances again.
                if not fits and len(tries) == len(left) > 1 and _clean_apart([f for f, _ in tries], im):
                    fits = [f for f, _ in tries]
                    break
                fit, i = max(tries, key=lambda t: t[0].score)
                fits.append(fit)
                left.pop(i)
            # Each instance fitted again with all the others' pixels explained: the
            # first fits of a split saw their neighbours' pixels as theirs to take,
            # and may lie across two of them.
            # (Not needed when every fit is clean already.)
            for _ in range(cfg.refits if len(fits) > 1 and not all(f.clean for f in fits) else 0):
                for i, f in enumerate(fits):
                    im.explained = _explain(before, fits[:i] + fits[i + 1 :], colour)
                    centroid = transform(polygon_centroid(shape.vertices)[None], *f.pose)[0]
                    fit = self._fit(k, im, labels, label, centroid, start=f.pose)
                    if fit is not None:
                        fits[i] = fit
            im.explained = _explain(before, fits, colour)
            spill = sum(f.spill for f in fits)
            # Pixels of the component explained, less each lower pixel under a fit as
            # _fit weighs it: two fits lying across two bars side by side explain most
            # of them but spill onto the table between.
            score = int(im.explained.ravel()[idx].sum()) - NEGATIVE_WEIGHT * spill
            if best is None or score > best[0]:
                best = (score, im.explained, [SceneObject(name, *f.pose) for f in fits])
            im.explained = before
            # Every instance fitted, each covering its own pixels and nothing that rules
            # it out: no other split can do better.
            if len(fits) == len(seeds) and all(f.clean for f in fits):
                break
        im.explained = best[1]
        return best[2]

    def _window(self, k: int, im: _Image, labels: np.ndarray, label: int, centre):
        """The evidence around ``centre`` for shape ``k`` and its score (`_Window`), or None
        when fewer than 5 unexplained pixels of component ``label`` lie near it."""
        cfg = self.config
        shape = self.library[self.names[k]]
        h = shape.height
        r = shape.radius + FIT_MARGIN
        rows, cols = im.window(centre, r, h)
        xy = im.P[rows, cols, :2]
        z = im.z[rows, cols]
        near = ((xy[..., 0] - centre[0]) ** 2 + (xy[..., 1] - centre[1]) ** 2) < r * r
        pos = (labels[rows, cols] == label) & ~im.explained[rows, cols] & near
        if int(pos.sum()) < 5:
            return None
        lower = z < h - cfg.top_band  # nan (no depth, off the table) compares False
        at_top = np.abs(z - h) < cfg.top_band
        ruled_out = lower | (
            at_top & ((im.cls[rows, cols] != self.colour_class[k]) | im.explained[rows, cols])
        )
        evidence = np.where(
            pos, np.float32(1.0), np.where(ruled_out, np.float32(-NEGATIVE_WEIGHT), np.float32(0.0))
        )
        origin = (cols.start, rows.start)
        v0 = shape.vertices
        score = PolygonScore(evidence, origin, im.cam.plane(h), v0, self._edge_samples(k, im))
        return _Window(score, rows, cols, origin, lower, np.asarray(centre, float), k)

    def _fit(self, k: int, im: _Image, labels: np.ndarray, label: int, centre, start=None, spread=0.0):
        """Fits shape ``k`` to the unexplained pixels of component ``label`` (of the image
        ``labels``) near ``centre``: from the pose ``start`` if given, else from the centre at
        angles over the shape's symmetry (and from centres up to ``spread`` m from it in x
        and y, for seeds that may lie between two instances). None when fewer than 5 pixels
        are left to fit."""
        win = self._window(k, im, labels, label, centre)
        if win is None:
            return None
        return self._fit_windows(im, [win], start=start, spread=spread)[0]

    def _fit_many(self, k: int, im: _Image, labels: np.ndarray, label: int, centres, spread=0.0) -> list:
        """`_fit` from each of ``centres`` at once (one batch of poses per search step):
        [(fit, index into centres)] for the centres with pixels left to fit."""
        wins = [(self._window(k, im, labels, label, c), i) for i, c in enumerate(centres)]
        wins = [(w, i) for w, i in wins if w is not None]
        if not wins:
            return []
        fits = self._fit_windows(im, [w for w, _ in wins], spread=spread)
        return [(f, i) for f, (_, i) in zip(fits, wins)]

    def _fit_windows(self, im: _Image, wins: list, start=None, spread=0.0) -> list:
        """Fits each window's shape in it, all at once (one batch of poses per search step,
        the windows told apart by owner): lone instances cost one search, not one each, and
        shapes share it too."""
        score = wins[0].score if len(wins) == 1 else PolygonScore.stack([w.score for w in wins])
        if start is not None:
            starts = np.array([[start]], float)
        else:
            # Centres: each window's own, or a grid around it (spread), each at every angle
            # over its shape's symmetry.
            g = np.linspace(-spread, spread, SPREAD_GRID) if spread else np.zeros(1)
            gx, gy = (a.ravel() for a in np.meshgrid(g, g))
            grid = np.stack([gx, gy], axis=1)
            per_win = []
            for w in wins:
                name = self.names[w.k]
                c_body = polygon_centroid(self.library[name].vertices)
                ths = np.arange(0.0, 2 * math.pi / self.sym[name], START_ANGLE_STEP)
                offs = np.column_stack(
                    [
                        np.cos(ths) * c_body[0] - np.sin(ths) * c_body[1],
                        np.sin(ths) * c_body[0] + np.cos(ths) * c_body[1],
                    ]
                )
                centres = w.centre + grid  # (C, 2)
                per_win.append(
                    np.stack(
                        [
                            centres[:, None, 0] - offs[None, :, 0],
                            centres[:, None, 1] - offs[None, :, 1],
                            np.broadcast_to(ths, (len(centres), len(ths))),
                        ],
                        axis=-1,
                    )
                )  # (C, A, 3)
            sizes = [x.shape[0] * x.shape[1] for x in per_win]
            owner = np.repeat(np.arange(len(wins)), sizes)
            s_all = score(np.concatenate([x.reshape(-1, 3) for x in per_win]), COARSE, owner=owner)
            picked = []
            for sw, cut in zip(per_win, np.split(s_all, np.cumsum(sizes)[:-1])):
                C, A = sw.shape[:2]
                s0 = cut.reshape(C, A)
                if C == 1:
                    # The best few distinct peaks of the (circular) angle sweep: the best start
                    # is not always in the right basin (a trapezoid seen from its centroid).
                    sf = s0[0]
                    peaks = [j for j in range(A) if sf[j] >= sf[j - 1] and sf[j] >= sf[(j + 1) % A]]
                    top = sorted(peaks, key=lambda j: -sf[j])[:REFINED_STARTS]
                    top = top[:1] + [j for j in top[1:] if sf[j] >= PEAK_SHARE * sf[top[0]]]
                    chosen = [sw[0, j] for j in top]
                else:
                    # The best angle of each centre competes; the best few centres go on.
                    j = np.argmax(s0, axis=1)
                    best = np.argsort(-s0[np.arange(C), j])[:REFINED_STARTS]
                    chosen = [sw[c, j[c]] for c in best]
                picked.append(chosen + [chosen[0]] * (REFINED_STARTS - len(chosen)))
            starts = np.array(picked)  # (F, REFINED_STARTS, 3)
        poses, values = quadratic_search(score, starts, np.array(FIT_STEP), FIT_TOL)
        return [
            self._finish(
                w,
                self.library[self.names[w.k]].vertices,
                self.library[self.names[w.k]].height,
                pose,
                value,
                im,
            )
            for w, pose, value in zip(wins, poses, values)
        ]

    @staticmethod
    def _finish(win, v0, h, best, value, im) -> _Fit:
        best = np.array(best, float)
        best[2] = math.remainder(best[2], 2 * math.pi)
        pose = tuple(float(v) for v in best)
        poly = im.cam.project(transform(v0, *pose), h)
        # Only the pixels of the polygon's bounding box can lie inside it.
        hgt, wid = win.lower.shape
        c0 = min(max(math.floor(poly[:, 0].min()) - win.origin[0], 0), wid)
        c1 = min(max(math.ceil(poly[:, 0].max()) + 1 - win.origin[0], c0), wid)
        r0 = min(max(math.floor(poly[:, 1].min()) - win.origin[1], 0), hgt)
        r1 = min(max(math.ceil(poly[:, 1].max()) + 1 - win.origin[1], r0), hgt)
        inside = np.zeros((hgt, wid), dtype=bool)
        inside[r0:r1, c0:c1] = pixels_inside(
            poly, (r1 - r0, c1 - c0), (win.origin[0] + c0, win.origin[1] + r0)
        )
        nxt = poly[np.arange(1, len(poly) + 1) % len(poly)]
        area = 0.5 * abs(float(np.sum(poly[:, 0] * nxt[:, 1] - nxt[:, 0] * poly[:, 1])))
        perimeter = float(np.linalg.norm(nxt - poly, axis=1).sum())
        clean = float(value) >= area - CLEAN_EDGE * perimeter
        return _Fit(pose, (win.rows, win.cols), inside, win.lower, float(value), clean, win.k)
