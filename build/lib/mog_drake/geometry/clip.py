"""Batched convex-polygon / axis-aligned-box measures, with no Python loop per polygon.

A batch is an array (N, K, 2) of closed CCW vertex loops; a polygon with fewer than K corners
is padded by repeating a corner (a zero-length edge), which changes neither its area nor its
extent. Both functions use fixed-size per-edge arrays (no compaction), so a whole scene's
candidate-object pairs are measured in a few dozen numpy operations.
"""

from __future__ import annotations

import numpy as np


def strip_extent(P: np.ndarray, lo: float, hi: float):
    """The x-range of each polygon's part inside the strip lo <= y <= hi, and whether that part
    has area. Exact, without clipping: the extreme x of a convex polygon within a strip is
    reached at a corner inside the strip or where an edge crosses one of the strip's lines.

    Returns (xmin, xmax, has_area); xmin = +inf, xmax = -inf where the part is empty.
    """
    x, y = P[..., 0], P[..., 1]
    # A convex polygon with area meets an open strip with area iff its y-range overlaps it.
    has_area = (y.max(axis=1) > lo) & (y.min(axis=1) < hi)
    inside = (y >= lo) & (y <= hi)
    cand_lo = np.where(inside, x, np.inf)
    cand_hi = np.where(inside, x, -np.inf)
    xn, yn = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    dy = np.where(yn == y, 1.0, yn - y)
    for c in (lo, hi):
        crosses = (y - c) * (yn - c) < 0
        xc = x + (c - y) / dy * (xn - x)
        cand_lo = np.minimum(cand_lo, np.where(crosses, xc, np.inf))
        cand_hi = np.maximum(cand_hi, np.where(crosses, xc, -np.inf))
    return cand_lo.min(axis=1), cand_hi.max(axis=1), has_area


def box_intersection_area(P: np.ndarray, box: tuple[float, float, float, float]) -> np.ndarray:
    """Area of (convex CCW polygon) ∩ (box xmin, xmax, ymin, ymax) for every polygon of P.

    Green's theorem: the area is 1/2 ∮ (x dy - y dx) around the intersection's boundary, which
    is made of (a) the polygon's edges clipped to the box (Liang-Barsky) and (b) the box's
    edges clipped to the polygon (Cyrus-Beck against its half-planes). A boundary piece that
    both share is counted once: a box edge lying on a polygon edge is dropped when the two
    run the same way (the polygon edge already counts it) and kept when they run opposite
    ways (the two cancel, as they must when the regions only touch).
    """
    x0, x1, y0, y1 = box
    p = P
    d = np.roll(P, -1, axis=1) - P
    # (a) Liang-Barsky: parameters [t0, t1] of each polygon edge inside the closed box.
    t0 = np.zeros(P.shape[:2])
    t1 = np.ones(P.shape[:2])
    ok = np.ones(P.shape[:2], dtype=bool)
    for pk, qk in (
        (-d[..., 0], p[..., 0] - x0),
        (d[..., 0], x1 - p[..., 0]),
        (-d[..., 1], p[..., 1] - y0),
        (d[..., 1], y1 - p[..., 1]),
    ):
        par = pk == 0
        ok &= ~(par & (qk < 0))
        r = np.where(par, 0.0, qk / np.where(par, 1.0, pk))
        t0 = np.where(~par & (pk < 0), np.maximum(t0, r), t0)
        t1 = np.where(~par & (pk > 0), np.minimum(t1, r), t1)
    span = np.where(ok & (t1 > t0), t1 - t0, 0.0)
    area = 0.5 * np.sum(span * (p[..., 0] * d[..., 1] - p[..., 1] * d[..., 0]), axis=1)

    # (b) Cyrus-Beck: parameters [s0, s1] of each box edge inside the polygon.
    e0 = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    ed = np.roll(e0, -1, axis=0) - e0
    # f_j(s) = cross(D_j, e0 + s ed - v_j) >= 0 inside half-plane j (CCW polygon).
    a = d[:, None, :, 0] * (e0[None, :, None, 1] - p[:, None, :, 1]) - d[:, None, :, 1] * (
        e0[None, :, None, 0] - p[:, None, :, 0]
    )
    b = d[:, None, :, 0] * ed[None, :, None, 1] - d[:, None, :, 1] * ed[None, :, None, 0]
    same_dir = (d[:, None, :, 0] * ed[None, :, None, 0] + d[:, None, :, 1] * ed[None, :, None, 1]) > 0
    par = b == 0
    excluded = par & ((a < 0) | ((a == 0) & same_dir))
    r = np.where(par, 0.0, -a / np.where(par, 1.0, b))
    s0 = np.max(np.where(~par & (b > 0), r, 0.0), axis=2, initial=0.0)
    s1 = np.min(np.where(~par & (b < 0), r, 1.0), axis=2, initial=1.0)
    valid = ~excluded.any(axis=2) & (s1 > s0)
    edge_cross = e0[:, 0] * ed[:, 1] - e0[:, 1] * ed[:, 0]
    area = area + 0.5 * np.sum(np.where(valid, s1 - s0, 0.0) * edge_cross[None, :], axis=1)
    return np.maximum(area, 0.0)
