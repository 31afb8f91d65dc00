"""Consolidating pushes in the plane (an extension beyond the paper; Drake-free).

A push moves one object along a straight line towards another with the closed jaws, so that
the next grasp takes both. The closed jaws are a square pusher ``2 t`` by ``plate_width``
(t: a plate's thickness) whose face meets the object; its centre starts ``PUSH_CLEARANCE``
behind the object, travels that far to touch it, and then ``distance`` more, which brings the
object to ``PUSH_GAP`` short of the one it joins (were it to slide without turning: the
physics check says where it really ends).

`push_candidates` lists such pushes for a scene, with geometry only; the planner ranks them
and asks the physics which are worth it (`mog_drake.planning.picking`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mog_drake.geometry.gripper import GripperGeometry
from mog_drake.geometry.polygon import convex_hull_ccw

PUSH_CLEARANCE = 0.008  # m between the pusher's face and the object before the push
PUSH_GAP = 0.006  # m left between the pushed object and the one it joins
PUSH_MARGIN = 0.004  # m the pusher keeps from every object but the pushed one
MIN_PUSH = 0.005  # m: a shorter push gains nothing
MAX_PUSH = 0.12  # m: a longer one slides the object too far to predict


@dataclass(frozen=True)
class Push:
    """A straight push of the closed jaws: their centre from ``start`` to ``end`` (x, y in
    the table frame, at grasp height), the closing axis at ``yaw``. ``target`` is the object
    pushed and ``toward`` the one it is pushed to; ``distance`` how far the object moves."""

    start: tuple[float, float]
    end: tuple[float, float]
    yaw: float
    target: int
    toward: int
    distance: float

    @property
    def direction(self) -> np.ndarray:
        d = np.subtract(self.end, self.start)
        return d / np.linalg.norm(d)

    @property
    def length(self) -> float:
        return float(np.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1]))

    def to_dict(self) -> dict:
        return {
            "start": [float(v) for v in self.start],
            "end": [float(v) for v in self.end],
            "yaw": float(self.yaw),
            "target": int(self.target),
            "toward": int(self.toward),
            "distance": float(self.distance),
        }


def ease(s: float) -> tuple[float, float]:
    """The cubic ease 0 -> 1 over s in [0, 1] (clamped), and its derivative in s."""
    s = min(max(s, 0.0), 1.0)
    return 3 * s * s - 2 * s**3, 6 * s - 6 * s * s


def push_duration(push: Push, speed: float) -> float:
    """How long a push takes at a mean ``speed`` (m/s) along the cubic ease (its peak speed
    is 1.5 times the mean), at least 0.2 s: the controller and the physics check both use it."""
    return max(push.length / speed, 0.2)


def contact_distance(P: np.ndarray, Q: np.ndarray, u) -> float:
    """How far convex polygon ``P`` (K, 2) can translate along unit vector ``u`` before it
    touches convex polygon ``Q`` (L, 2), which it does not overlap: the smallest t >= 0 at
    which P + t u meets Q (0 when they touch), inf when it never does."""
    P, Q, u = np.asarray(P, float), np.asarray(Q, float), np.asarray(u, float)

    def rays(points, poly, d):
        a, b = poly, np.roll(poly, -1, axis=0)
        e = b - a  # (L, 2) edges
        w = a[None, :, :] - points[:, None, :]  # (K, L, 2)
        den = d[0] * e[:, 1] - d[1] * e[:, 0]  # cross(d, e)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[..., 0] * e[:, 1] - w[..., 1] * e[:, 0]) / den
            s = (w[..., 0] * d[1] - w[..., 1] * d[0]) / den
        ok = (np.abs(den) > 1e-12) & (s >= -1e-9) & (s <= 1 + 1e-9) & (t >= -1e-9)
        return np.min(t[ok]) if ok.any() else np.inf

    return float(max(min(rays(P, Q, u), rays(Q, P, -u)), 0.0))


def pusher_square(center, u, gripper: GripperGeometry) -> np.ndarray:
    """The closed jaws' footprint (4, 2), CCW, centred at ``center`` with its face normal to
    ``u``: 2 plate thicknesses along u, a plate's width across."""
    u = np.asarray(u, float)
    n = np.array([-u[1], u[0]])
    a, b = gripper.plate_thickness, gripper.plate_width / 2
    c = np.asarray(center, float)
    return np.array([c - a * u - b * n, c + a * u - b * n, c + a * u + b * n, c - a * u + b * n])


def _support(P: np.ndarray, u: np.ndarray) -> float:
    return float(np.max(P @ u))


def push_between(polys, i: int, j: int, gripper: GripperGeometry, keep_out=()) -> Push | None:
    """The push of object ``i`` towards object ``j`` along the line of their centres, or None
    when it is too short or too long, when the object would meet another first, when the
    pusher would start on, or sweep into, any other object, or when the pusher or the object
    would enter one of the ``keep_out`` boxes (xmin, xmax, ymin, ymax: the bin's walls)."""
    ci, cj = polys.centers[i], polys.centers[j]
    d = cj - ci
    if np.linalg.norm(d) < 1e-9:
        return None
    u = d / np.linalg.norm(d)
    Pi = polys.polygon(i)
    travel = contact_distance(Pi, polys.polygon(j), u) - PUSH_GAP
    if not MIN_PUSH <= travel <= MAX_PUSH:
        return None
    back = _support(Pi - ci, -u)  # the object's extent behind its centre
    start = ci - u * (back + gripper.plate_thickness + PUSH_CLEARANCE)
    sweep = PUSH_CLEARANCE + travel
    # Only objects whose bounding circles come near the swept band can be in the way.
    length = float((ci + u * (travel + polys.radii[i]) - start) @ u)
    near = near_path(polys, start, u, length, max(polys.radii[i], gripper.plate_width) + PUSH_MARGIN)
    for k in near:  # the object's path: nothing else before the one it joins
        if k not in (i, j) and contact_distance(Pi, polys.polygon(k), u) < travel + PUSH_GAP:
            return None
    # The pusher neither starts within PUSH_MARGIN of another object nor sweeps into one (the
    # pushed object stops PUSH_GAP short of j, the pusher a plate behind it).
    grown = _grow(pusher_square(start, u, gripper), PUSH_MARGIN)
    for k in near:
        if k != i and contact_distance(grown, polys.polygon(k), u) < sweep:
            return None
    end = start + u * sweep
    if keep_out:
        swept = (
            convex_hull_ccw(np.concatenate([Pi, Pi + u * travel])),
            convex_hull_ccw(np.concatenate([grown, grown + u * sweep])),
        )
        if any(overlaps_box(P, box) for P in swept for box in keep_out):
            return None
    return Push(
        (float(start[0]), float(start[1])),
        (float(end[0]), float(end[1])),
        float(np.arctan2(u[1], u[0])),
        int(i),
        int(j),
        float(travel),
    )


def overlaps_box(P: np.ndarray, box) -> bool:
    """Whether convex polygon ``P`` (K, 2), CCW, overlaps the axis-aligned box (xmin, xmax,
    ymin, ymax) by more than touching: no separating axis among the table's x and y and
    ``P``'s edge normals."""
    x0, x1, y0, y1 = box
    if P[:, 0].max() <= x0 or P[:, 0].min() >= x1 or P[:, 1].max() <= y0 or P[:, 1].min() >= y1:
        return False
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    e = P[np.arange(1, len(P) + 1) % len(P)] - P
    n = np.stack([e[:, 1], -e[:, 0]], axis=1)  # outward normals of a CCW polygon
    # Apart along edge k's normal when every corner lies beyond that edge.
    beyond = ((corners[None, :, :] - P[:, None, :]) * n[:, None, :]).sum(axis=2) >= 0
    return not beyond.all(axis=1).any()


def near_path(polys, start, u, length: float, margin: float) -> np.ndarray:
    """Indices of the objects whose bounding circles come within ``margin`` (m) of the segment
    from ``start`` along unit vector ``u`` for ``length`` (m)."""
    a = np.asarray(start, float)
    t = np.clip((polys.centers - a) @ u, 0.0, length)
    gap = np.linalg.norm(polys.centers - (a + t[:, None] * u), axis=1)
    return np.flatnonzero(gap < polys.radii + margin)


def _grow(square: np.ndarray, margin: float) -> np.ndarray:
    c = square.mean(axis=0)
    r = square - c
    scale = 1 + margin / np.min(np.linalg.norm(r, axis=1))
    return c + r * scale


def push_candidates(
    polys, movable, gripper: GripperGeometry | None = None, reach: float = 0.12, keep_out=()
) -> list[Push]:
    """Pushes of each object of ``movable`` towards every other object whose centre lies
    within ``reach`` (m) of its own (see `push_between`), shortest first."""
    gripper = gripper or GripperGeometry()
    out = []
    for i in movable:
        dist = np.linalg.norm(polys.centers - polys.centers[i], axis=1)
        for j in np.flatnonzero((dist > 0) & (dist <= reach)):
            p = push_between(polys, int(i), int(j), gripper, keep_out)
            if p is not None:
                out.append(p)
    return sorted(out, key=lambda p: p.distance)
