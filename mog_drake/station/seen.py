"""Where the simulated camera sees each object: its pose estimate's error kept in the table's
plane however the object lies, and two objects never seen one inside the other (`SeenPoses`)."""

from dataclasses import dataclass, field

import numpy as np
import shapely
from pydrake.math import RigidTransform, RotationMatrix

from mog_drake.sim.realism import seen_in_body


@dataclass
class _Seen:
    """One object whose camera image is off its pose (`SeenPoses`)."""

    body: object
    geometry: object  # its perception geometry's id
    shape: object  # that geometry's shape
    offset: np.ndarray  # its pose error (dx, dy, dyaw)
    X_BG: object  # where the geometry is placed in the body frame now
    points: np.ndarray  # 3 x N: its prism's corners in its body frame
    # The world's up axis in the body frame when last looked at (as the scene put it at first).
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    share: float = 1.0  # the share of its pose error it is seen with now


class SeenPoses:
    """Keeps where the camera sees each object (its perception geometry, off its true pose by
    the world's pose error: `add_prism`'s ``seen``) in the table's plane whichever way up the
    object lies (`realism.seen_in_body`). The error is registered in the body frame, which is the
    table's plane only while the object stands as the scene put it: a bar knocked onto its side
    would carry the error's dy along its now vertical axis, seen millimetres under the table (a
    7 mm bar vanished from the depth image for good) or above its top (an unrecognised blob).

    Two objects are never seen one inside the other: a camera sees each where it lies, and
    only the pose estimate drawn from its image is off. Where two objects' errors would put
    their images over each other by more than ``OVERLAP_M2`` beyond what their bodies overlap,
    both are seen with a share of their errors (the largest of ``SHARES`` that parts them).
    Left whole, two bars lying side by side 9 mm apart were drawn as one bar with a stub, and
    the planner never saw the other for 20 attempts.

    ``update`` re-places the geometry of each object whose tilt or share moved it by more than
    ``TOL_M`` or ``TOL_RAD``, at most every ``period`` s of simulated time; the shares are set
    again when the table comes to rest after a move: an object that just fell is seen with the
    old placement until then, and images wait for the table to be still."""

    TOL_M, TOL_RAD = 5e-4, np.radians(0.5)
    OVERLAP_M2 = 1e-6
    LOW_M = 0.08  # an object whose frame is lower than this (m above the table) may lie on it
    SHARES = (0.75, 0.5, 0.25, 0.0)

    def __init__(self, plant, scene_graph, bodies: dict, offsets: dict, period: float, points: dict):
        from pydrake.geometry import Role

        self.plant, self.scene_graph, self.period = plant, scene_graph, period
        inspector = scene_graph.model_inspector()
        self.items = []
        for i, off in offsets.items():
            frame = plant.GetBodyFrameIdOrThrow(bodies[i].index())
            (gid,) = inspector.GetGeometries(frame, Role.kPerception)
            self.items.append(
                _Seen(
                    bodies[i],
                    gid,
                    inspector.GetShape(gid),
                    np.asarray(off, float),
                    inspector.GetPoseInFrame(gid),
                    points[i],
                )
            )
        self.source = plant.get_source_id()
        self.last = -np.inf
        self.at = None  # (positions, rotations) of the objects at the last look
        self.parted = None  # ... when their shares of their errors were last set (`shares`)
        self.moves = 0  # geometries re-placed

    def _moved(self, since, p: np.ndarray, R: np.ndarray) -> bool:
        """Whether an object low enough to lie on the table (`LOW_M`) moved more than TOL_M or
        turned more than TOL_RAD ``since`` then (objects the arm carries, say, do not count)."""
        p0, R0 = since
        low = p[:, 2] < self.LOW_M
        cos = (np.einsum("kij,kij->k", R0[low], R[low]) - 1.0) / 2.0
        return bool(
            np.abs(p[low] - p0[low]).max(initial=0.0) > self.TOL_M or (cos < np.cos(self.TOL_RAD)).any()
        )

    def _outline(self, item: _Seen, p, R, share: float):
        """An object's outline on the table (its xy hull) as the camera sees it with ``share`` of its error."""
        R_BG, p_BG = seen_in_body(R, share * item.offset)
        P = R @ (R_BG @ item.points + p_BG[:, None]) + p[:, None]
        return shapely.convex_hull(shapely.MultiPoint(P[:2].T))

    def shares(self, p: np.ndarray, R: np.ndarray) -> np.ndarray:
        """The share of its error each object is seen with, its body at ``p[k]``, ``R[k]``: 1,
        or less where its image and a neighbour's would overlap more than their bodies do."""
        low = np.flatnonzero(p[:, 2] < self.LOW_M)
        body = {k: self._outline(self.items[k], p[k], R[k], 0.0) for k in low}
        seen = {k: self._outline(self.items[k], p[k], R[k], 1.0) for k in low}
        share = np.ones(len(self.items))
        outlines = [seen[k] for k in low]
        i, j = shapely.STRtree(outlines).query(outlines, predicate="intersects")
        for a, b in zip(low[i[i < j]], low[j[i < j]]):
            both = body[a].intersection(body[b]).area + self.OVERLAP_M2
            if seen[a].intersection(seen[b]).area <= both:
                continue
            for s in self.SHARES:
                sa = self._outline(self.items[a], p[a], R[a], s)
                sb = self._outline(self.items[b], p[b], R[b], s)
                if sa.intersection(sb).area <= both:
                    break
            share[a], share[b] = min(share[a], s), min(share[b], s)
        return share

    def update(self, root_context) -> None:
        t = root_context.get_time()
        if t - self.last < self.period - 1e-9:
            return
        self.last = t
        poses = self.plant.get_body_poses_output_port().Eval(self.plant.GetMyContextFromRoot(root_context))
        X = [poses[item.body.index()] for item in self.items]
        p = np.array([x.translation() for x in X])
        R = np.array([x.rotation().matrix() for x in X])
        # The images parted again once the table is at rest (nothing moved since the last
        # look) and something moved since they were last parted: images wait for a still table.
        first = self.parted is None
        still = self.at is not None and not self._moved(self.at, p, R)
        self.at = (p, R)
        shares = [item.share for item in self.items]
        if first or (still and self._moved(self.parted, p, R)):
            shares, self.parted = self.shares(p, R), (p, R)
        sgc = None
        for item, R_WB, share in zip(self.items, R, shares):
            # Where it is seen depends on its tilt (its up axis in its own frame), not on its
            # yaw, and on the share of its error: both unchanged since the last look, nothing to do.
            if not first and np.abs(R_WB[2] - item.up).max() < 1e-3 and share == item.share:
                continue
            item.up = R_WB[2].copy()
            item.share = share
            R_BG, p_BG = seen_in_body(R_WB, share * item.offset)
            X_new = RigidTransform(RotationMatrix(R_BG), p_BG)
            turn = item.X_BG.rotation().InvertAndCompose(X_new.rotation()).ToAngleAxis().angle()
            if (
                np.linalg.norm(X_new.translation() - item.X_BG.translation()) <= self.TOL_M
                and turn <= self.TOL_RAD
            ):
                continue
            sgc = sgc or self.scene_graph.GetMyMutableContextFromRoot(root_context)
            self.scene_graph.ChangeShape(sgc, self.source, item.geometry, item.shape, X_new)
            item.X_BG = X_new
            self.moves += 1
