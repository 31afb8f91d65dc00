"""Depth to points, points to pixels, colour to chromaticity."""

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
