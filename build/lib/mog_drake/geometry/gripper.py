"""The parallel-jaw gripper in the plane: jaw rectangles and the inner region S (paper Fig. 4).

A grasp is u = (x, y, theta) in the table frame (Sec. 3). In the grasp frame the closing
axis is +x: the left jaw sits at -x, the right jaw at +x, both closing towards the origin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mog_drake.errors import MogError


@dataclass(frozen=True)
class GripperGeometry:
    """Planar model of a Robotiq-2F-85-like gripper. The one source of truth for its sizes.

    Defaults are the paper authors' model: plate centres 85 mm apart when open, plates
    10 mm thick along the closing axis and 20 mm wide across it, so S is 75 mm x 20 mm.
    """

    opening: float = 0.085  # distance between plate centres when open (m)
    plate_thickness: float = 0.010  # along the closing axis (m)
    plate_width: float = 0.020  # across the closing axis (m)

    def __post_init__(self) -> None:
        for name in ("opening", "plate_thickness", "plate_width"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise MogError(f"gripper {name} must be a positive finite length, got {v}")
        if self.plate_thickness >= self.opening:
            raise MogError("gripper plate_thickness must be smaller than the opening")

    @property
    def w_g(self) -> float:
        """Initial stroke w_g(t0): the free distance between the open jaws' inner faces."""
        return self.opening - self.plate_thickness

    @property
    def s_size(self) -> tuple[float, float]:
        """Size of the inner rectangular region S: (along closing axis, across)."""
        return self.w_g, self.plate_width

    @property
    def reach_radius(self) -> float:
        """Radius around the grasp point that contains both jaws and S."""
        return float(np.hypot(self.opening / 2 + self.plate_thickness / 2, self.plate_width / 2))

    def boxes(self) -> dict[str, tuple[float, float, float, float]]:
        """Grasp-frame axis-aligned boxes (xmin, xmax, ymin, ymax) of S and the two jaws."""
        hw, hy, t = self.w_g / 2, self.plate_width / 2, self.plate_thickness
        return {
            "S": (-hw, hw, -hy, hy),
            "left_jaw": (-hw - t, -hw, -hy, hy),
            "right_jaw": (hw, hw + t, -hy, hy),
        }

    def rectangles(self, grasp) -> dict[str, np.ndarray]:
        """Table-frame corner arrays (4, 2), CCW, of S and both jaws for one grasp u."""
        x, y, th = (float(v) for v in grasp)
        c, s = np.cos(th), np.sin(th)
        out = {}
        for name, (x0, x1, y0, y1) in self.boxes().items():
            local = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
            out[name] = np.stack(
                [c * local[:, 0] - s * local[:, 1] + x, s * local[:, 0] + c * local[:, 1] + y], 1
            )
        return out


def to_grasp_frame(points: np.ndarray, grasps: np.ndarray) -> np.ndarray:
    """Table-frame points (..., K, 2) expressed in the frames of grasps (..., 3), broadcast."""
    g = np.asarray(grasps, dtype=float)
    c, s = np.cos(g[..., 2])[..., None], np.sin(g[..., 2])[..., None]
    dx = points[..., 0] - g[..., 0][..., None]
    dy = points[..., 1] - g[..., 1][..., None]
    return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)


#: The inner opening of the open jaws (m): w_g of the default gripper, 75 mm. The controller
#: opens to it and the stations start at it.
OPEN_WIDTH = round(GripperGeometry().w_g, 9)


def clear_of_boxes(grasps, boxes, gripper: GripperGeometry | None = None) -> np.ndarray:
    """(B,) True where the open gripper's footprint (both jaws and the region S between them,
    the rectangle they sweep as they close) overlaps none of ``boxes``, axis-aligned
    (xmin, xmax, ymin, ymax) regions of the table that the jaws must not enter (the bin's
    walls: taller than anything the jaws reach down to). Touching is allowed. A separating
    axis test: the rectangle and a box are apart when their projections are apart on the
    table's x or y axis or on one of the rectangle's two axes."""
    gripper = gripper or GripperGeometry()
    g = np.atleast_2d(np.asarray(grasps, dtype=float))
    clear = np.ones(len(g), dtype=bool)
    a = gripper.opening / 2 + gripper.plate_thickness / 2  # half length along the closing axis
    b = gripper.plate_width / 2
    cos, sin = np.cos(g[:, 2]), np.sin(g[:, 2])
    c, s = np.abs(cos), np.abs(sin)
    for x0, x1, y0, y1 in boxes:
        cx, cy, ex, ey = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 2, (y1 - y0) / 2
        dx, dy = cx - g[:, 0], cy - g[:, 1]
        along = np.abs(dx * cos + dy * sin)
        across = np.abs(-dx * sin + dy * cos)
        apart = (
            (np.abs(dx) >= ex + a * c + b * s)
            | (np.abs(dy) >= ey + a * s + b * c)
            | (along >= a + ex * c + ey * s)
            | (across >= b + ex * s + ey * c)
        )
        clear &= apart
    return clear
