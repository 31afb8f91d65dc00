"""Depth to points, colour to chromaticity."""

import numpy as np


def backproject(
    depth: np.ndarray, X_WC: np.ndarray, fx: float, fy: float, cx: float, cy: float
) -> np.ndarray:
    """Depth image (H, W) -> (H, W, 3) points in the world frame (nan where depth is invalid)."""
    h, w = depth.shape
    u, v = np.meshgrid(np.arange(w), np.arange(h))
    d = np.where(np.isfinite(depth) & (depth > 0), depth, np.nan)
    pc = np.stack([(u - cx) * d / fx, (v - cy) * d / fy, d], axis=-1)
    return pc @ X_WC[:3, :3].T + X_WC[:3, 3]


def chromaticity(rgb: np.ndarray) -> np.ndarray:
    c = np.asarray(rgb, dtype=float)[..., :3]
    return c / np.maximum(c.max(axis=-1, keepdims=True), 1e-6)
