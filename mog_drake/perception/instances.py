"""Fitting the library's shapes to the object pixels of one colour (steps 3-4 of
`mog_drake.perception.perceiver`): one instance per connected component, or several split
from touching objects, each fitted where its projected top face covers most evidence."""

import math
from dataclasses import dataclass

import numpy as np

from mog_drake.geometry.polygon import polygon_centroid, transform
from mog_drake.perception.fitting import (
    FIT_MARGIN,
    NEGATIVE_WEIGHT,
    PolygonScore,
    pixels_inside,
    quadratic_search,
    seedings,
)
from mog_drake.scenes import SceneObject

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
# perimeter. Right fits lose about 0.3 on a rendered image (outline pixels partly covered: the
# part of a pixel outside the top counts against the fit) and more on a real camera's, whose
# edges carry mixed and flying pixels: on the realistic cell's images at the D435's rated
# noise, 0.51 (median) and 0.79 (90th percentile) of 227 right fits; 0.74 and 1.22 at four
# times the noise. A fit across two instances loses 2.5 per pixel of table under it, 1.9
# per pixel of perimeter (median). An instance not clean makes its split try every seeding.
CLEAN_EDGE = 0.8
# Instances a component may hold beyond its estimate from its visible area (`count`).
MORE_INSTANCES = 2
# A split with one more instance whose fits share more pixels than this share of one top is
# not taken: instances that touch share the pixels along their edge, one invented between
# two real ones half of its own. In rows of 2-5 upright bars on the paper's cell (128
# images), the instances found that way shared 0-30 pixels (one 102: 0.36 of a thick bar's
# top) and the invented ones 111-162 (0.48-0.56 of a top).
SHARED = 0.4


@dataclass
class FitWindow:
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
    return all(f.clean for f in fits) and _shared(fits, im) == 0


def _shared(fits: list[_Fit], im) -> int:
    """How many pixels lie inside two fits or more."""
    count = np.zeros(im.shape, dtype=np.uint8)
    for f in fits:
        count[f.window] += f.inside
    return int((count > 1).sum())


_CORNERS = ((-1, -1), (1, -1), (1, 1), (-1, 1))


class EvidenceImage:
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


class InstanceFitter:
    """The fitting half of `Perceiver` (its ``config``, ``library``, ``names`` and shapes'
    projected outlines are the perceiver's)."""

    def _edge_samples(self, k: int, im: EvidenceImage) -> tuple:
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

    def count(
        self,
        k: int,
        im: EvidenceImage,
        labels,
        label: int,
        idx,
        n_est: int,
        *,
        colour,
        rng,
        area_px,
        lone=None,
    ):
        """The instances of shape ``k`` in component ``label`` (its flat pixel indices at the
        shape's top ``idx``): ``n_est`` of them split apart (or ``lone``: one fit made already,
        its pixels explained), then one more as long as a split leaves unexplained as much of
        the top as makes a component an instance (``min_fraction`` of the shape's area), and
        the split with one more adds that many pixels to the score and its fits share fewer
        than SHARED of a top's pixels. The visible area undercounts touching instances: three
        thick bars touching on the paper's cell showed 2.45 bars' tops, were split in two, and
        a bar was missed. Their pixels left explained."""
        most_left = self.config.min_fraction * self.area[k]
        areas = area_px.ravel()[idx]

        def too_little_left() -> bool:
            return float(areas[~im.explained.ravel()[idx]].sum()) < most_left

        if lone is None:
            before = im.explained.copy()
            objects, score, _ = self._split(k, im, labels, label, idx, n_est, colour=colour, rng=rng)
        else:
            objects = [SceneObject(self.names[k], *lone.pose)]
            if too_little_left():  # most lone instances: no copy of the image's mask
                return objects
            before = im.explained.copy()
            before.ravel()[idx] = False
            score = int(im.explained.ravel()[idx].sum()) - NEGATIVE_WEIGHT * lone.spill
        instance = self.area[k] / float(areas.mean())  # pixels of one top
        gain = self.config.min_fraction * instance  # the score one more instance must add
        n = n_est
        while n < n_est + MORE_INSTANCES:
            if too_little_left():
                break
            kept = im.explained
            im.explained = before.copy()
            found, more, shared = self._split(k, im, labels, label, idx, n + 1, colour=colour, rng=rng)
            if more - score < gain or shared > SHARED * instance:
                im.explained = kept
                break
            objects, score, n = found, more, n + 1
        return objects

    def _split(self, k: int, im: EvidenceImage, labels, label: int, idx, n_est: int, *, colour, rng) -> tuple:
        """Fits ``n_est`` touching instances of shape ``k`` to component ``label`` (its flat
        pixel indices ``idx``): the objects of the best split, their pixels left explained, its
        score and how many pixels lie inside two of its fits."""
        cfg = self.config
        name = self.names[k]
        shape = self.library[name]
        pts = im.xy[idx]
        best = None  # (score of the split, explained mask, objects)
        for seeds in seedings(pts, min(n_est, len(idx)), cfg.separation_tries, rng):
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
                best = (score, im.explained, [SceneObject(name, *f.pose) for f in fits], _shared(fits, im))
            im.explained = before
            # Every instance fitted, each covering its own pixels and nothing that rules
            # it out: no other split can do better.
            if len(fits) == len(seeds) and all(f.clean for f in fits):
                break
        im.explained = best[1]
        return best[2], best[0], best[3]

    def _window(self, k: int, im: EvidenceImage, labels: np.ndarray, label: int, centre):
        """The evidence around ``centre`` for shape ``k`` and its score (`FitWindow`), or None
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
        return FitWindow(score, rows, cols, origin, lower, np.asarray(centre, float), k)

    def _fit(
        self, k: int, im: EvidenceImage, labels: np.ndarray, label: int, centre, start=None, *, spread=0.0
    ):
        """Fits shape ``k`` to the unexplained pixels of component ``label`` (of the image
        ``labels``) near ``centre``: from the pose ``start`` if given, else from the centre at
        angles over the shape's symmetry (and from centres up to ``spread`` m from it in x
        and y, for seeds that may lie between two instances). None when fewer than 5 pixels
        are left to fit."""
        win = self._window(k, im, labels, label, centre)
        if win is None:
            return None
        return self._fit_windows(im, [win], start=start, spread=spread)[0]

    def _fit_many(
        self, k: int, im: EvidenceImage, labels: np.ndarray, label: int, centres, spread=0.0
    ) -> list:
        """`_fit` from each of ``centres`` at once (one batch of poses per search step):
        [(fit, index into centres)] for the centres with pixels left to fit."""
        wins = [(self._window(k, im, labels, label, c), i) for i, c in enumerate(centres)]
        wins = [(w, i) for w, i in wins if w is not None]
        if not wins:
            return []
        fits = self._fit_windows(im, [w for w, _ in wins], spread=spread)
        return [(f, i) for f, (_, i) in zip(fits, wins)]

    def _fit_windows(self, im: EvidenceImage, wins: list, start=None, spread=0.0) -> list:
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
