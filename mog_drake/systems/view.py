"""Whether the arm hides the table from the camera: when the next image may be taken."""

import numpy as np

from mog_drake.geometry.polygon import convex_hull_ccw, convex_inside_distance
from mog_drake.perception.pointcloud import Pinhole


def _image_polygon(cam: Pinhole, rect, z: float = 0.0) -> np.ndarray:
    x0, x1, y0, y1 = rect
    return cam.project(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float), z)


def _inside_margin(poly: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Signed distance (pixels) of points inside a convex image polygon: > 0 inside."""
    return convex_inside_distance(poly, uv[:, 0], uv[:, 1])


class ArmView:
    """``arm_view(q, holding)``: True when no part of the arm at joint positions ``q`` (nor,
    when ``holding``, what may hang from its fingers) hides any pixel of the perceived table
    from the camera, outside the regions perception ignores (the bin). ``arm_view.clear_of(q,
    holding, prisms)``: True when it hides none of ``prisms`` (the objects still on the table)
    and what it holds hangs above the heights perception looks at.

    The arm is its kinematic chain from the base's foot to the fingertips, sampled every
    ``step`` m, each sample a ball of ``radius`` m (the UR5's links are at most 0.06 m thick);
    a held object hangs at most ``hang`` m below the fingertips. ``frames(q)``: the chain's
    points (as `SafetyMonitor.frames`); ``X_WC``, ``intrinsics``: the camera's pose and
    intrinsics; ``table``, ``ignore``: the perceived table and its ignored regions."""

    def __init__(
        self,
        frames,
        base_xyz,
        X_WC,
        intrinsics,
        table,
        ignore=(),
        *,
        radius=0.07,
        hang=0.06,
        step=0.02,
        above=0.08,
    ):
        self._frames = frames
        self._base = np.asarray(base_xyz, float)
        self._cam = Pinhole(X_WC, intrinsics)
        self._table = _image_polygon(self._cam, table)
        self._ignore = [_image_polygon(self._cam, r) for r in ignore]
        self._radius, self._hang, self._step, self._above = radius, hang, step, above

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

    def _balls(self, q, holding: bool):
        """The arm's sample points in the image, and each ball's radius there (pixels); None
        when a point is at the lens."""
        uv, depth = self._cam.pixels(self.points(q, holding))
        if np.any(depth <= 0.05):
            return None
        return uv, self._radius * self._cam.fx / depth

    def clear_of(self, q, holding: bool, prisms) -> bool:
        """``prisms``: (vertices (V, 2) in the table frame, top height) of the objects left on
        the table. True when the arm (and, ``holding``, what hangs from it, which must then be
        ``above`` m over the table, higher than perception looks) hides none of them: their
        top faces and side walls as the camera sees them, the balls' radius around them."""
        if holding:
            f = self._frames(np.asarray(q, float))
            low = min(f[k][2] for k in f if "fingertip" in k) - self._hang
            if low < self._above:
                return False
        balls = self._balls(q, holding)
        if balls is None:
            return False
        uv, margin = balls
        for verts, top in prisms:
            seen = np.vstack(
                [
                    self._cam.project(np.asarray(verts, float), top),
                    self._cam.project(np.asarray(verts, float), 0.0),
                ]
            )
            hull = convex_hull_ccw(seen)
            if np.any(_inside_margin(hull, uv) > -margin):
                return False
        return True

    def __call__(self, q, holding: bool = False) -> bool:
        balls = self._balls(q, holding)
        if balls is None:
            return False  # at the lens: hides everything
        uv, margin = balls
        over = _inside_margin(self._table, uv) > -margin
        for poly in self._ignore:  # wholly over an ignored region hides nothing perceived
            over &= ~(_inside_margin(poly, uv) > margin)
        return not bool(over.any())
