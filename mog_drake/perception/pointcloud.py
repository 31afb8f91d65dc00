"""Depth to points, points to pixels, colour to chromaticity."""

import functools

import numpy as np


def backproject(
    depth: np.ndarray, X_WC: np.ndarray, fx: float, fy: float, cx: float, cy: float
) -> np.ndarray:
    """Depth image (H, W) -> (H, W, 3) points in the world frame (nan where depth is invalid),
    in the depth image's float type (float32 from a camera: 0.03 um at a metre)."""
    h, w = depth.shape
    dtype = depth.dtype if depth.dtype in (np.float32, np.float64) else np.float64
    d = np.where(np.isfinite(depth) & (depth > 0), depth, np.nan).astype(dtype, copy=False)
    R, t = np.asarray(X_WC[:3, :3], float), np.asarray(X_WC[:3, 3], float)
    # A point is d * (ray in the camera frame): its world coordinates are d * (R ray) + t,
    # with R ray separable in u and v.
    ru = ((np.arange(w) - cx) / fx).astype(dtype)
    rv = ((np.arange(h) - cy) / fy).astype(dtype)
    out = np.empty((h, w, 3), dtype=dtype)
    for i in range(3):
        out[..., i] = d * (
            dtype.type(R[i, 0]) * ru[None, :] + dtype.type(R[i, 1]) * rv[:, None] + dtype.type(R[i, 2])
        )
        out[..., i] += dtype.type(t[i])
    return out


class Pinhole:
    """World points to pixel coordinates (u, v), the pixel centres at integers (as
    `backproject` reads them). ``X_WC``: the camera's pose; ``intrinsics``: (fx, fy, cx, cy)."""

    def __init__(self, X_WC: np.ndarray, intrinsics):
        X_WC = np.asarray(X_WC, float)
        self.R_CW = X_WC[:3, :3].T
        self.p_CW = -self.R_CW @ X_WC[:3, 3]
        self._R, self._p = self.R_CW.tolist(), self.p_CW.tolist()
        self.fx, self.fy, self.cx, self.cy = (float(v) for v in intrinsics)

    def plane(self, z: float) -> np.ndarray:
        """The 3 x 3 homography from (x, y, 1) on the horizontal plane at height z to
        homogeneous pixel coordinates."""
        K = np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])
        R = self.R_CW
        return K @ np.column_stack([R[:, 0], R[:, 1], z * R[:, 2] + self.p_CW])

    def project_point(self, x: float, y: float, z: float) -> tuple[float, float]:
        """One point's pixel coordinates (plain floats: no array overhead)."""
        R, p = self._R, self._p
        c = [R[i][0] * x + R[i][1] * y + R[i][2] * z + p[i] for i in range(3)]
        return self.fx * c[0] / c[2] + self.cx, self.fy * c[1] / c[2] + self.cy

    def pixels(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points (..., 3) -> their pixel coordinates (..., 2) and depths (...,)."""
        pc = np.asarray(points, float) @ self.R_CW.T + self.p_CW
        uv = np.stack(
            [self.fx * pc[..., 0] / pc[..., 2] + self.cx, self.fy * pc[..., 1] / pc[..., 2] + self.cy], -1
        )
        return uv, pc[..., 2]

    def project(self, xy: np.ndarray, z: float) -> np.ndarray:
        """Points (..., 2) on the horizontal plane at height z -> (..., 2) pixel coordinates."""
        xy = np.asarray(xy, float)
        return self.pixels(np.concatenate([xy, np.full(xy.shape[:-1] + (1,), float(z))], axis=-1))[0]


def chromaticity(rgb: np.ndarray) -> np.ndarray:
    c = np.asarray(rgb, dtype=float)[..., :3]
    return c / np.maximum(c.max(axis=-1, keepdims=True), 1e-6)


# Pixels darker than this (their brightest channel, of 1) have no colour to speak of: shadows.
DARK = 0.15


# How far (chromaticity) a pixel may be from the table's colour or an object's to be taken for
# it: the library's nearest colour to the table is 0.32 away; shading changes no chromaticity,
# and a camera's colour noise a few hundredths.
COLOUR_TOL = 0.15


@functools.lru_cache(maxsize=8)
def _colour_lut(table: tuple, palette: bytes) -> np.ndarray:
    """`colour_labels`' table of 32^3 colours (the table's chromaticity to 0.01: a cell's images
    share one)."""
    K = np.vstack([np.asarray(table, np.float32)[None], np.frombuffer(palette, np.float32).reshape(-1, 3)])
    levels = (np.arange(32, dtype=np.float32) * 8 + 3.5)[:, None, None, None]
    grid = np.concatenate(
        np.broadcast_arrays(levels, levels.transpose(1, 0, 2, 3), levels.transpose(1, 2, 0, 3)), -1
    ).reshape(-1, 3)
    top = grid.max(axis=-1)
    d = ((grid / top[:, None])[:, None, :] - K[None, :, :]) ** 2
    d = d.sum(-1)
    nearest = np.argmin(d, axis=1)
    lut = (nearest - 1).astype(np.int32)
    lut[d[np.arange(len(d)), nearest] > COLOUR_TOL**2] = len(K) - 1
    lut[top < DARK * 255.0] = -2
    lut.flags.writeable = False
    return lut


def colour_labels(rgb: np.ndarray, palette: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Each pixel's colour (H, W int32): the index into ``palette`` (chromaticities, K x 3) of
    the nearest colour within COLOUR_TOL, K where no colour of the palette nor the table's is
    within it (an object of another colour), -1 where the table's own chromaticity ``table``
    is the nearest within it, -2 where the pixel is too dark to tell (DARK). Looked up in a
    table of 32 levels per channel (a chromaticity within 0.02 of the pixel's own), built for
    this call: 32^3 colours classified cost a tenth of 640 x 480 pixels."""
    lut = _colour_lut(tuple(np.round(np.asarray(table, float), 2)), np.asarray(palette, np.float32).tobytes())
    c = np.asarray(rgb)[..., :3] >> 3
    return lut[(c[..., 0].astype(np.int32) << 10) | (c[..., 1].astype(np.int32) << 5) | c[..., 2]]


def smooth_within(depth: np.ndarray, label: np.ndarray, radius: int) -> np.ndarray:
    """``depth`` (H, W) averaged over a (2 radius + 1)^2 window (rows, then columns), each pixel
    over the pixels of its own ``label`` with a depth: noise averages out, an object's edge
    does not blur into the table (a colour boundary), and a hole takes its neighbours' depth."""
    d = np.asarray(depth, np.float32)
    if radius <= 0:
        return d.copy()
    for axis in (1, 0):
        total = np.zeros(d.shape, np.float32)
        count = np.zeros(d.shape, np.float32)
        n = d.shape[axis]
        for o in range(-radius, radius + 1):
            src = [slice(None)] * 2
            dst = [slice(None)] * 2
            src[axis] = slice(max(o, 0), n + min(o, 0))
            dst[axis] = slice(max(-o, 0), n - max(o, 0))
            ds, ls = d[tuple(src)], label[tuple(src)]
            same = (ls == label[tuple(dst)]) & np.isfinite(ds)
            total[tuple(dst)] += np.where(same, ds, 0.0)
            count[tuple(dst)] += same
        d = np.where(count > 0, total / np.maximum(count, 1.0), np.float32(np.nan))
    return d


def replace_outliers(depth: np.ndarray, label: np.ndarray, keep: np.ndarray, tol: float) -> np.ndarray:
    """``depth`` with each pixel of ``keep`` that lies more than ``tol`` (m) off the median of
    the pixels of its own ``label`` in its 3 x 3 neighbourhood (itself included, holes left
    out) set to that median: a flying pixel at an object's edge (a depth between its top and
    the table behind) takes its neighbours' depth, before averaging would spread it."""
    d = np.asarray(depth, np.float32)
    rows, cols = np.nonzero(keep)
    if rows.size == 0:
        return d.copy()
    h, w = d.shape
    stack = np.full((9, rows.size), np.nan, np.float32)
    k = 0
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            r, c = np.clip(rows + dr, 0, h - 1), np.clip(cols + dc, 0, w - 1)
            same = label[r, c] == label[rows, cols]
            stack[k] = np.where(same, d[r, c], np.nan)
            k += 1
    stack.sort(axis=0)  # nan last
    n = np.isfinite(stack).sum(axis=0)
    lo = stack[np.maximum((n - 1) // 2, 0), np.arange(rows.size)]
    hi = stack[np.maximum(n // 2, 0), np.arange(rows.size)]
    med = 0.5 * (lo + hi)
    out = d.copy()
    own = d[rows, cols]
    far = (n > 0) & (np.abs(own - med) > tol)
    out[rows[far], cols[far]] = med[far]
    return out


def depth_noise(depth: np.ndarray, mask: np.ndarray) -> float:
    """The depth's per-pixel noise (m, RMS) over ``mask`` (a flat surface: the table), from the
    differences between horizontal neighbours (robust: 1.4826 x their median absolute value,
    over sqrt 2); 0 with fewer than 100 pairs."""
    d = np.asarray(depth, np.float32)
    rows = d[::2]  # every other row: plenty, and half the cost
    pair = mask[::2, 1:] & mask[::2, :-1] & np.isfinite(rows[:, 1:]) & np.isfinite(rows[:, :-1])
    diff = rows[:, 1:][pair] - rows[:, :-1][pair]
    if diff.size < 100:
        return 0.0
    return float(1.4826 * np.median(np.abs(diff)) / np.sqrt(2.0))
