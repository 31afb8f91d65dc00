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

from mog_drake.config import in_range
from mog_drake.errors import MogError
from mog_drake.geometry.polygon import transform
from mog_drake.perception.fitting import (
    components,
    near_polygon,
    outline,
    separate_overlaps,
    symmetry_order,
)
from mog_drake.perception.instances import EvidenceImage, InstanceFitter
from mog_drake.perception.pointcloud import (
    DARK,
    Pinhole,
    backproject,
    chromaticity,
    colour_labels,
    depth_noise,
    replace_outliers,
    smooth_within,
)
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
    # splits along separation_tries + 1 directions for two (see seedings). Its instances are
    # fitted best first; the split whose fits explain most of its pixels, less their spill
    # onto lower surfaces, is kept, and one whose every fit is clean ends the search.
    separation_tries: int = 2
    # m: fits of three or more instances start from centres this far around each seed (a
    # k-means centre can fall between two bars lying side by side).
    split_spread: float = 0.006
    refits: int = 1  # passes fitting each instance of a split again, the others' pixels explained
    # Heights from the table's plane fitted in each image (least squares on the pixels within
    # table_band of the table, twice, the second time on those within 3 residuals' RMS of
    # the first fit), not from z = 0: a camera whose calibration is off by a tenth of a
    # degree sees the table sloped by a millimetre or more across the image, which with depth
    # noise lifts patches of table past min_height. Off, heights are the camera's own.
    fit_table: bool = False
    table_band: float = 0.006  # m

    def check(self) -> None:
        """Refuses, at load, settings perception cannot work with (the key named)."""
        in_range(self.min_height, "perception.min_height (m)", 0, 0.1)
        in_range(self.max_height, "perception.max_height (m)", self.min_height, 1.0)
        for key in ("top_band", "wall_margin", "split_spread", "table_band"):
            in_range(getattr(self, key), f"perception.{key} (m)", 0, 0.05)
        in_range(self.min_fraction, "perception.min_fraction", 0, 1)
        in_range(self.unknown_area, "perception.unknown_area (m^2)", 0, 0.1)
        for key, most in (("separation_tries", 16), ("refits", 8)):
            in_range(getattr(self, key), f"perception.{key}", 0, most, lo_open=False)


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


def table_plane(P: np.ndarray, ok: np.ndarray, band: float, stride: int = 4) -> np.ndarray:
    """The table's height under each point of P (H, W, 3): the plane z = a x + b y + c fitted
    to the points of ``ok`` within ``band`` of z = 0 (every ``stride``-th row and column),
    then again to those within 3 RMS residuals of that fit. Zero where too few points."""
    sub = P[::stride, ::stride].reshape(-1, 3)
    keep = ok[::stride, ::stride].ravel() & (np.abs(sub[:, 2]) < band)
    coef = np.zeros(3)
    for _ in range(2):
        if keep.sum() < 100:
            return np.zeros(P.shape[:2])
        A = np.column_stack([sub[keep, 0], sub[keep, 1], np.ones(int(keep.sum()))])
        coef = np.linalg.lstsq(A, sub[keep, 2], rcond=None)[0]
        r = sub[:, 2] - (coef[0] * sub[:, 0] + coef[1] * sub[:, 1] + coef[2])
        rms = float(np.sqrt(np.mean(r[keep] ** 2)))
        keep = ok[::stride, ::stride].ravel() & (np.abs(r) < max(3 * rms, 1e-4))
    return np.nan_to_num(coef[0] * P[..., 0] + coef[1] * P[..., 1] + coef[2])


def smoothing_radius(noise: float) -> int:
    """The half-width (pixels) of the window `smooth_within` averages depth over, for a
    camera whose depth noise on the table is ``noise`` (m RMS): 0 below 1.5 mm (a rendered
    image, or a good camera close up), then wide enough to bring it under about 1.5 mm (a box
    of (2 r + 1)^2 pixels divides it by up to 2 r + 1; at most 3)."""
    if noise < 0.0015:
        return 0
    return int(min(max(math.ceil((noise / 0.0015 - 1) / 2), 1), 3))


def _inside(P: np.ndarray, rect) -> np.ndarray:
    """Which points of P (..., 3) lie strictly inside rect (xmin, xmax, ymin, ymax) in x, y."""
    x0, x1, y0, y1 = rect
    return (P[..., 0] > x0) & (P[..., 0] < x1) & (P[..., 1] > y0) & (P[..., 1] < y1)


class Perceiver(InstanceFitter):
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
        self.heights = np.array([self.library[n].height for n in names])
        self.area = [self.library[n].area for n in names]

    def _unexplained(self, found, im, obj, area_px) -> list:
        """Object pixels no fitted polygon explains (a prism knocked onto its side, say, or
        something not in the library), as blobs (pixel indices) larger than ``unknown_area``:
        reported, so nobody calls such a table clear."""
        cfg, P = self.config, im.P
        covered = np.zeros(im.shape, dtype=bool)
        for o in found:
            shape = self.library[o.shape]
            rows, cols = im.window((o.x, o.y), shape.radius + cfg.wall_margin, 0.0)
            poly = transform(shape.vertices, o.x, o.y, o.theta)
            # Its top and its side walls:
            covered[rows, cols] |= near_polygon(P[rows, cols, 0], P[rows, cols, 1], poly, cfg.wall_margin)
        _, blobs = components(np.flatnonzero(obj & ~covered), im.shape)
        return [idx for idx in blobs if area_px.ravel()[idx].sum() > cfg.unknown_area]

    def changed_pixels(
        self,
        before: np.ndarray,
        after: np.ndarray,
        X_WC,
        intrinsics,
        tol: float = 0.004,
        settle_px: int = 2,
        *,
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
        # A noisy camera: both images averaged as `perceive` averages them, and the threshold
        # raised to four times the noise left in their difference.
        noise = depth_noise(before, np.isfinite(before))
        radius = smoothing_radius(noise)
        if radius:
            flat_label = np.zeros(after.shape, np.int32)
            before, after = (
                smooth_within(before, flat_label, radius),
                smooth_within(after, flat_label, radius),
            )
            tol = max(tol, 4 * math.sqrt(2) * noise / (2 * radius + 1))
        Pa = backproject(after, X_WC, *intrinsics)
        region = np.isfinite(Pa[..., 2]) & _inside(Pa, self.table)
        for r in self.ignore:
            region &= ~_inside(Pa, r)
        zb = backproject(before, X_WC, *intrinsics)[..., 2]
        hidden = ~(zb < cfg.max_height)  # the arm, or no depth: nothing known there
        za = Pa[..., 2]
        if still:
            hidden |= ~(za < cfg.max_height)
        if cfg.fit_table and not still:  # heights from the table's plane, as `perceive`
            # measures them (for `appeared`, which a still check leaves out): on a miscalibrated
            # camera the table itself would otherwise appear where the arm was
            za = za - table_plane(Pa, region & ~hidden, cfg.table_band)
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

    def _heights(self, rgb: np.ndarray, depth: np.ndarray, X_WC: np.ndarray, intrinsics):
        """(P, z, cls, depth): the points of the perceived table (H, W, 3; nan elsewhere), their
        heights above the table, each object pixel's colour class (-1 on every other pixel) and
        the depth they were computed from.

        Colour decides what can be an object: a pixel nearer the table's own colour (the
        median colour of the pixels seen at the table's height) than to any object's, or too
        dark to tell, is never an object pixel, however its depth is off. Depth is then
        averaged within each colour (`smooth_within`) over a window as wide as the noise seen
        on the table needs (`smoothing_radius`): heights hold their top band at several times
        a camera's rated noise, and a hole takes its neighbours' depth."""
        cfg = self.config
        P0 = backproject(depth, X_WC, *intrinsics)
        region = _inside(P0, self.table)
        for r in self.ignore:
            region &= ~_inside(P0, r)
        seen = region & np.isfinite(P0[..., 2])
        bright = rgb[..., :3].max(axis=-1) >= DARK * 255
        flat = seen & bright & (np.abs(P0[..., 2]) < cfg.table_band)
        some = flat if flat.sum() >= 100 else seen & bright
        table = np.median(chromaticity(rgb[..., :3][some][::7]), axis=0)  # a sample: the table is most
        label = colour_labels(rgb, self.chroma, table)
        # Each shape's colour class; an object of no library colour gets a class of its own,
        # which no shape fits: an unrecognised blob.
        classes = np.append(self.colour_class, len(self.names))
        label = np.where(label >= 0, classes[np.maximum(label, 0)], label)
        label[~region] = -3  # off the perceived table: averaged with nothing on it
        noise = depth_noise(depth, seen & (label == -1))
        radius = smoothing_radius(noise)
        if radius:  # flying pixels out first: averaged, they would pull a thin bar's top down
            depth = replace_outliers(depth, label, seen & (label >= 0), max(4 * noise, cfg.top_band))
        smoothed = smooth_within(depth, label, radius)
        if radius == 0 and not np.isfinite(depth[region]).all():
            # A hole takes its nearest neighbours' depth, however little the noise.
            smoothed = np.where(np.isfinite(depth), smoothed, smooth_within(depth, label, 1))
        P = backproject(smoothed, X_WC, *intrinsics)
        ok = region & np.isfinite(P[..., 2])
        P[~ok] = np.nan
        if cfg.fit_table:
            P[..., 2] -= table_plane(P, ok & (label == -1), cfg.table_band)
        z = P[..., 2]
        cls = np.where(ok & (label >= 0) & (z > cfg.min_height) & (z < cfg.max_height), label, -1)
        return P, z, cls.astype(np.int32), smoothed

    def perceive(
        self, rgb: np.ndarray, depth: np.ndarray, X_WC: np.ndarray, intrinsics, seed: int = 0
    ) -> Scene:
        """rgb (H, W, 3 or 4) uint8, depth (H, W) m, X_WC 4x4 camera pose, intrinsics (fx, fy, cx, cy)."""
        cfg = self.config
        fx, fy, cx, cy = intrinsics
        depth = np.asarray(depth, np.float32).reshape(rgb.shape[:2])
        X_WC = np.asarray(X_WC, float)
        P, z, cls, depth = self._heights(rgb, depth, X_WC, intrinsics)
        obj = cls >= 0
        # Footprint of one pixel on a plane facing the camera at its depth: its weight in areas.
        area_px = np.where(obj, depth.astype(np.float64) ** 2 / (fx * fy), 0.0)
        obj_px = np.flatnonzero(obj)
        obj_cls = cls.ravel()[obj_px]
        obj_z = z.ravel()[obj_px]
        # Each object pixel is at the top of the shape of its colour whose height is nearest
        # its own: a bar upright (30 mm) or on its side, a cube (30 mm) or on its side (25 mm),
        # told apart by the nearer height, not by two overlapping bands.
        gap = np.abs(obj_z[:, None] - self.heights[None, :])
        gap[obj_cls[:, None] != self.colour_class[None, :]] = np.inf
        obj_top = self.heights[np.argmin(gap, axis=1)] if len(obj_px) else obj_z
        im = EvidenceImage(P, z, cls, Pinhole(X_WC, intrinsics))
        rng = np.random.default_rng(seed)
        found: list[SceneObject] = []
        # Large shapes first: their fits then mask their pixels for the smaller ones. The
        # lone instances of shapes that cannot take each other's pixels (another colour, or
        # a top at another height) are fitted in one batch, the touching instances of each
        # shape after them; a shape that can take a pending one's pixels waits for its fits.
        order = sorted(range(len(self.names)), key=lambda k: -self.area[k])
        found_by: dict[int, list[SceneObject]] = {k: [] for k in order}
        pending: list[tuple] = []  # (k, labels, colour mask, several) whose lone windows wait
        wins: list[tuple] = []  # (a lone instance's FitWindow, (labels, label, its pixels at the top))

        def flush():
            colours = {k: colour for k, _, colour, _ in pending}
            fits = self._fit_windows(im, [w for w, _ in wins]) if wins else []
            for f in fits:
                im.explained[f.window] |= f.inside & colours[f.k][f.window]
            for f, (_, (labels, label, idx)) in zip(fits, wins):
                found_by[f.k].extend(
                    self.count(
                        f.k, im, labels, label, idx, 1, colour=colours[f.k], rng=rng, area_px=area_px, lone=f
                    )
                )
            for k, labels, colour, several in pending:
                for label, idx, n_est in several:
                    found_by[k].extend(
                        self.count(k, im, labels, label, idx, n_est, colour=colour, rng=rng, area_px=area_px)
                    )
            pending.clear()
            wins.clear()

        by_colour: dict[int, tuple] = {}  # colour class -> its components (`components`)
        for k in order:
            if any(self._interact(k, j) for j, *_ in pending):
                flush()
            shape = self.library[self.names[k]]
            area = self.area[k]
            mine = obj_px[
                (obj_cls == self.colour_class[k])
                & (obj_top == shape.height)
                & (np.abs(obj_z - shape.height) < cfg.top_band)
            ]
            if not len(mine):
                continue
            # Components of the object's colour (any height), each holding its pixels at this
            # top: noise that drops a few pixels of a top out of the band does not cut it in
            # pieces, each too small to count.
            c = self.colour_class[k]
            if c not in by_colour:
                by_colour[c] = components(obj_px[obj_cls == c], z.shape)
            at_top = np.zeros(z.size, bool)
            at_top[mine] = True
            labels = np.where(at_top.reshape(z.shape), by_colour[c][0], 0)
            members = [m[at_top[m]] for m in by_colour[c][1]]
            colour = cls == self.colour_class[k]
            lone, several = [], []
            for label, idx in enumerate(members, start=1):
                visible = float(area_px.ravel()[idx].sum())
                if visible >= cfg.min_fraction * area:
                    n_est = max(int(round(visible / area)), 1)
                    (lone if n_est == 1 else several).append((label, idx, n_est))
            lone_windows = (
                (self._window(k, im, labels, label, im.xy[idx].mean(axis=0)), (labels, label, idx))
                for label, idx, _ in lone
            )
            wins.extend(w for w in lone_windows if w[0] is not None)
            pending.append((k, labels, colour, several))
        flush()
        found = [o for k in order for o in found_by[k]]
        unknown = self._unexplained(found, im, obj, area_px)
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
            {"vertices": hull.round(5).tolist(), "top": round(float(np.percentile(zf[idx], 95)), 5)}
            for idx in unknown
            if (hull := outline(im.xy[idx])) is not None
        ]
        scene.meta["overlap_corrections"] = moved
        return scene
