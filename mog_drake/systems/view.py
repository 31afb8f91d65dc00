"""Whether the arm hides the table from the camera: when the next image may be taken."""

import numpy as np

from mog_drake.perception.pointcloud import Pinhole


def _image_polygon(cam: Pinhole, rect, z: float = 0.0) -> np.ndarray:
    x0, x1, y0, y1 = rect
    return cam.project(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float), z)


def _inside_margin(poly: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Signed distance (pixels) of points inside a convex image polygon: > 0 inside."""
    e = np.roll(poly, -1, axis=0) - poly
    wind = np.sign(np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])) or 1.0
    n = wind * np.stack([-e[:, 1], e[:, 0]], axis=1) / np.linalg.norm(e, axis=1, keepdims=True)  # inward
    return ((uv[:, None, :] - poly[None]) * n[None]).sum(-1).min(axis=1)


class ArmView:
    """``arm_view(q, holding)``: True when no part of the arm at joint positions ``q`` (nor,
    when ``holding``, what may hang from its fingers) hides any pixel of the perceived table
    from the camera, outside the regions perception ignores (the bin).

    The arm is its kinematic chain from the base's foot to the fingertips, sampled every
    ``step`` m, each sample a ball of ``radius`` m (the UR5's links are at most 0.06 m thick);
    a held object hangs at most ``hang`` m below the fingertips. ``frames(q)``: the chain's
    points (as `SafetyMonitor.frames`); ``X_WC``, ``intrinsics``: the camera's pose and
    intrinsics; ``table``, ``ignore``: the perceived table and its ignored regions."""

    def __init__(
        self, frames, base_xyz, X_WC, intrinsics, table, ignore=(), radius=0.07, hang=0.06, step=0.02
    ):
        self._frames = frames
        self._base = np.asarray(base_xyz, float)
        self._cam = Pinhole(X_WC, intrinsics)
        self._X_WC = np.asarray(X_WC, float)
        self._table = _image_polygon(self._cam, table)
        self._ignore = [_image_polygon(self._cam, r) for r in ignore]
        self._radius, self._hang, self._step = radius, hang, step

    def points(self, q, holding: bool) -> np.ndarray:
        f = self._frames(np.asarray(q, float))
        chain = [self._base, *(f[k] for k in f if "fingertip" not in k)]
        pts = [self._base[None]]
        for a, b in zip(chain[:-1], chain[1:]):
            n = max(int(np.ceil(np.linalg.norm(b - a) / self._step)), 1)
            pts.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
        tips = [f[k] for k in f if "fingertip" in k]
        for tip in tips:
            pts.append(np.linspace(chain[-1], tip, 4))
            if holding:
                pts.append(tip + np.outer(np.linspace(0.0, 1.0, 4), [0.0, 0.0, -self._hang]))
        return np.vstack(pts)

    def __call__(self, q, holding: bool = False) -> bool:
        p = self.points(q, holding)
        R, t = self._X_WC[:3, :3], self._X_WC[:3, 3]
        depth = (p - t) @ R[:, 2]
        if np.any(depth <= 0.05):
            return False  # at the lens: hides everything
        uv = np.stack(
            [
                self._cam.fx * ((p - t) @ R[:, 0]) / depth + self._cam.cx,
                self._cam.fy * ((p - t) @ R[:, 1]) / depth + self._cam.cy,
            ],
            axis=1,
        )
        margin = self._radius * self._cam.fx / depth  # a ball's radius in pixels
        over = _inside_margin(self._table, uv) > -margin
        for poly in self._ignore:  # wholly over an ignored region hides nothing perceived
            over &= ~(_inside_margin(poly, uv) > margin)
        return not bool(over.any())
