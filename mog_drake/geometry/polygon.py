"""Convex polygons: validation, frictionless final diameters (paper Sec. 4 and Eq. 5).

Pure numpy. A polygon is an (N, 2) array of vertices, counter-clockwise, in metres.
"""

from __future__ import annotations

import numpy as np

from mog_drake.errors import MogError

# Lengths below this (m) are treated as zero: 1e-9 m is a nanometre, far below any
# modelling or sensing precision, and far above float round-off on metre-scale data.
LENGTH_TOL = 1e-9
# Shortest edge a shape may have (m): final_diameters decides contact geometry to 1e-7 m, so
# an edge shorter than that is no edge to it (a 10 nm edge hid a triangle's grasps).
MIN_EDGE = 1e-6


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _corner(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether o -> a -> b turns left at a by more than LENGTH_TOL: a lies further than that
    from the chord o-b, on its right. (A test on the cross product alone, which scales with
    the chord's length, kept a point 1e-12 m off an edge on one chain and dropped it on the
    other.)"""
    return _cross(o, a, b) > LENGTH_TOL * float(np.hypot(b[0] - o[0], b[1] - o[1]))


def convex_inside_distance(poly: np.ndarray, x, y) -> np.ndarray:
    """Signed distance inside a convex polygon (V, 2), wound either way, of points given by
    arrays ``x`` and ``y`` (any broadcastable shapes): the least distance to an edge's line,
    > 0 inside, < 0 outside (a lower bound of the true distance out there; exact near an
    edge). nan coordinates give nan."""
    p = np.asarray(poly, float)
    q = p[np.arange(1, len(p) + 1) % len(p)]  # each edge's end (np.roll costs more than this)
    e = q - p
    wind = np.sign(np.sum(p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1])) or 1.0
    n = wind * np.stack([-e[:, 1], e[:, 0]], axis=1) / np.hypot(e[:, 0], e[:, 1])[:, None]  # inward
    # d = n . (point - vertex) = n . point - n . vertex, each edge's line in one product.
    c = (n * p).sum(axis=1)
    out = None
    for (nx, ny), ci in zip(n.tolist(), c.tolist()):
        d = nx * x + ny * y - ci
        if out is None:
            out = d
        elif isinstance(out, np.ndarray):
            np.minimum(out, d, out=out)
        else:
            out = np.minimum(out, d)
    return out


def convex_hull_ccw(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2-D points (Andrew's monotone chain), CCW from the lowest-leftmost point;
    points within LENGTH_TOL of an edge (collinear, or a near-duplicate of a corner) are
    dropped. (Not shapely's hull: it keeps a point 1e-12 m off an edge as a corner, and the
    sliver edge it makes cost a library shape its stable grasps: tests/geometry/test_polygon.py.)"""
    pts = np.unique(np.asarray(points, dtype=float), axis=0)  # sorted by x, then y
    if len(pts) < 3:
        return pts
    lower: list[np.ndarray] = []
    for p in pts:
        while len(lower) >= 2 and not _corner(lower[-2], lower[-1], p):
            lower.pop()
        lower.append(p)
    upper: list[np.ndarray] = []
    for p in pts[::-1]:
        while len(upper) >= 2 and not _corner(upper[-2], upper[-1], p):
            upper.pop()
        upper.append(p)
    hull = lower[:-1] + upper[:-1]
    # The chain starts at the leftmost point and never tests it: drop it (and so on) when it
    # lies on the edge joining its neighbours.
    while len(hull) > 3 and not _corner(hull[-1], hull[0], hull[1]):
        hull.pop(0)
    return np.array(hull)


def validate_convex_polygon(points, name: str) -> np.ndarray:
    """Checks that ``points`` are the corners of a convex polygon and returns them CCW.

    The points may come in any order (the hull is taken). Refused, with a message naming
    ``name``: non-finite numbers, fewer than 3 distinct points, repeated points, points that
    are all collinear, points that are not corners of the hull (the polygon is not convex,
    or a point lies on an edge), and edges shorter than MIN_EDGE.
    """
    try:
        pts = np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise MogError(f"shape '{name}': vertices must be a list of [x, y] number pairs") from None
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise MogError(f"shape '{name}': vertices must be a list of [x, y] pairs, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise MogError(f"shape '{name}': vertices contain a non-finite number")
    distinct = np.unique(pts, axis=0)
    if len(distinct) != len(pts):
        raise MogError(f"shape '{name}': repeated vertex")
    if len(distinct) < 3:
        raise MogError(f"shape '{name}': needs at least 3 distinct vertices, got {len(distinct)}")
    hull = convex_hull_ccw(pts)
    if len(hull) < 3 or polygon_area(hull) <= LENGTH_TOL**2:
        raise MogError(f"shape '{name}': vertices are collinear (zero area)")
    if len(hull) != len(pts):
        missing = [p for p in pts if not np.any(np.all(np.isclose(hull, p, rtol=0, atol=0), axis=1))]
        raise MogError(
            f"shape '{name}': not a convex polygon: vertex ({missing[0][0]:g}, {missing[0][1]:g}) "
            "is not a corner of the convex hull"
        )
    edges = np.linalg.norm(np.roll(hull, -1, axis=0) - hull, axis=1)
    if edges.min() < MIN_EDGE:
        raise MogError(f"shape '{name}': an edge is {edges.min():.3g} m long, under {MIN_EDGE:g} m")
    return hull


def polygon_area(vertices: np.ndarray) -> float:
    """Signed shoelace area (positive for CCW)."""
    v = np.asarray(vertices, dtype=float)
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def polygon_centroid(vertices: np.ndarray) -> np.ndarray:
    """Area centroid of a simple polygon."""
    v = np.asarray(vertices, dtype=float)
    x, y = v[:, 0], v[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a = cross.sum() / 2
    return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6 * a)


def edge_directions(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit edge directions and outward unit normals of a CCW polygon (edge i: v_i -> v_i+1)."""
    v = np.asarray(vertices, dtype=float)
    e = np.roll(v, -1, axis=0) - v
    e = e / np.linalg.norm(e, axis=1, keepdims=True)
    n = np.stack([e[:, 1], -e[:, 0]], axis=1)  # outward for CCW
    return e, n


def final_diameters(vertices: np.ndarray, tol: float = 1e-7, merge_tol: float = 1e-5) -> np.ndarray:
    """Every frictionless stable final diameter d_f of a convex polygon (paper Sec. 4, Fig. 2).

    Under the frictionless point-contact model a parallel-jaw grasp is in equilibrium only if
    the two contact normals are opposite and collinear (Eq. 1), i.e. one jaw lies flat on an
    edge e and the other touches the polygon at its farthest point from e's line:

    * (i) a parallel edge whose projection onto e overlaps e with positive length, or
    * (ii) a single vertex whose perpendicular foot lies inside e.

    Vertex-vertex contacts are unstable and excluded (Sec. 4). The diameter of such a grasp
    is the distance from e's line to that farthest point. Returns the distinct values,
    sorted ascending. ``tol`` decides contact geometry; values closer than ``merge_tol``
    (default 0.01 mm, the precision of published vertex tables) are one diameter.

    The minimum width is always among them: turning the jaws either way from it widens the
    polygon, so it is stable even where its foot lies within ``tol`` of a corner (a sliver's
    acute corner puts it there).
    """
    v = np.asarray(vertices, dtype=float)
    e, n = edge_directions(v)
    widths = np.array([float(((v - v[i]) @ (-n[i])).max()) for i in range(len(v))])
    out: list[float] = [float(widths.min())]
    for i in range(len(v)):
        a, b = v[i], v[(i + 1) % len(v)]
        depth = (v - a) @ (-n[i])  # distance of every vertex inward from edge i's line
        d = widths[i]
        far = np.flatnonzero(depth >= d - tol)
        # projections onto edge i of the farthest vertices, and of edge i itself
        s_far = (v[far] - a) @ e[i]
        s_edge = float((b - a) @ e[i])
        if len(far) == 1:
            # A foot exactly at an endpoint of e is a vertex-vertex contact: unstable.
            stable = tol < s_far[0] < s_edge - tol
        else:
            lo, hi = max(0.0, float(s_far.min())), min(s_edge, float(s_far.max()))
            stable = hi - lo > tol
        if stable:
            out.append(d)
    vals = np.sort(np.array(out))
    merged: list[float] = []
    for x in vals:
        if not merged or x - merged[-1] > merge_tol:
            merged.append(float(x))
    return np.array(merged)


def transform(vertices: np.ndarray, x: float, y: float, theta: float) -> np.ndarray:
    """Body-frame vertices placed at pose (x, y, theta) in the table frame."""
    c, s = np.cos(theta), np.sin(theta)
    v = np.asarray(vertices, dtype=float)
    return np.stack([c * v[:, 0] - s * v[:, 1] + x, s * v[:, 0] + c * v[:, 1] + y], axis=1)


def axis_gap(a, b):
    """Angle (rad) between two axes, i.e. directions modulo pi (elementwise, broadcasting)."""
    return np.abs(np.remainder(np.asarray(a) - np.asarray(b) + np.pi / 2, np.pi) - np.pi / 2)


def diameter_function(vertices: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """D(phi): the polygon's extent along each direction phi (the jaw opening that closes on
    it along that axis). Periodic in pi."""
    v = np.asarray(vertices, dtype=float)
    d = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    p = d @ v.T
    return p.max(axis=-1) - p.min(axis=-1)


def squeeze_basins(
    vertices: np.ndarray, closing_angles, samples: int = 1440
) -> tuple[np.ndarray, np.ndarray]:
    """Where a frictionless squeeze takes a single polygon, and how robustly.

    Jaws closing along phi turn the polygon so that its extent D(phi) shrinks, until D is at
    a local minimum (a jaw flat on an edge: a final diameter). For each closing angle this
    returns that minimum's angle phi* (table frame, in [0, pi)) and the basin margin: the
    angle from phi* to the nearer local maximum of D, i.e. how far the held polygon must be
    turned about the vertical before the squeeze drives it on to another final diameter.
    A thin bar held end to end has a margin of atan(width / length) (8 deg for 50 x 7 mm);
    held across, the rest of the half turn. D is sampled every pi / ``samples``.
    """
    phi = np.arange(samples) * np.pi / samples
    D = diameter_function(vertices, phi)
    nxt, prv = np.roll(np.arange(samples), -1), np.roll(np.arange(samples), 1)
    # steepest descent on the periodic grid: every sample points at its lower neighbour
    step = np.where(D[nxt] < D[prv], nxt, prv)
    down = np.where(np.minimum(D[nxt], D[prv]) < D, step, np.arange(samples))
    basin = np.arange(samples)
    for _ in range(samples):  # pointer jumping to the fixed points (local minima)
        nb = down[basin]
        if np.array_equal(nb, basin):
            break
        basin = nb
    is_max = (D >= D[nxt]) & (D >= D[prv]) & ~((D == D[nxt]) & (D == D[prv]))
    maxima = np.flatnonzero(is_max)
    if len(maxima) == 0:  # a circle-like D: no preferred turn
        margin_at = np.full(samples, np.pi / 2)
    else:
        margin_at = axis_gap(phi[:, None], phi[maxima][None, :]).min(axis=1)
    q = (
        np.round(np.remainder(np.asarray(closing_angles, dtype=float), np.pi) / np.pi * samples).astype(int)
        % samples
    )
    m = basin[q]
    return phi[m], margin_at[m]
