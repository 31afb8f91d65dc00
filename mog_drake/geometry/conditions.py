"""The two necessary conditions of a frictionless multi-object push-grasp (paper Sec. 5).

For a batch of grasps u = (x, y, theta) and a group of objects this computes, all at once:

* o_i^s = S ∩ O_i and A_i = Area(o_i^s) for every group object (Sec. 5.2);
* b_l, b_r: the distances from the left / right jaw to the nearest material inside S, and the
  initial multi-object diameter h0 = w_g - (b_l + b_r) (Eq. 3);
* h_fmin = sum of the group's d_fmin (Eq. 6);
* the diameter condition h0 >= h_fmin (Eq. 7) and the relaxed area condition A_i(0) > 0 for
  every group object (Eq. 9);
* whether either jaw collides with any object, in the group or not (GenGraspCands, Sec. 6.2);
* an extension, the frictional diameter condition h0 >= h_fmin_columns (see
  `GraspEvaluation.diameter_ok_columns`).

Objects outside the group whose material lies inside S are allowed: the closing jaws push them
too, so they may be lifted as a bonus. They bound the jaws' travel, so they count in b_l, b_r
and h0 (the jaws must cross the free space up to the first material, whichever object it
belongs to: h_f <= h0 still holds); they do not enter h_fmin or the area condition, which
speak of the group. With no non-group object in S this is exactly the paper's definition.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mog_drake.geometry.clip import box_intersection_area, strip_extent
from mog_drake.geometry.gripper import GripperGeometry, to_grasp_frame
from mog_drake.geometry.polygon import LENGTH_TOL

# Areas at or below this (m^2) count as zero: 1e-10 m^2 = 1e-4 mm^2, a 10 um x 10 um sliver.
AREA_EPS = 1e-10


@dataclass(frozen=True)
class PolygonSet:
    """The objects of a scene as arrays, in the table frame.

    vertices: (M, K, 2) CCW corners, rows with fewer than K corners padded by repeating one.
    counts: (M,) number of real corners. centers: (M, 2) pose positions. radii: (M,) largest
    distance from a center to its corners. d_fmin: (M,) minimum final diameters.
    """

    vertices: np.ndarray
    counts: np.ndarray
    centers: np.ndarray
    radii: np.ndarray
    d_fmin: np.ndarray

    def __len__(self) -> int:
        return len(self.counts)

    def polygon(self, i: int) -> np.ndarray:
        return self.vertices[i, : self.counts[i]]


@dataclass
class GraspEvaluation:
    """Geometry figures and verdicts of a batch of B grasps on one group (see module doc)."""

    grasps: np.ndarray  # (B, 3)
    group: np.ndarray  # (n,) object indices
    areas: np.ndarray  # (B, n) A_i of the group objects
    h0: np.ndarray  # (B,) 0 where no material is inside S
    b_l: np.ndarray  # (B,) nan where no material is inside S
    b_r: np.ndarray  # (B,)
    h_fmin: float
    collision_free: np.ndarray  # (B,) bool
    in_s: np.ndarray  # (B, M) bool: object has material inside S
    # (B,) the largest summed d_fmin of one column: group objects whose parts in S overlap
    # across the jaws (in y, the plates' width) are one column, lined up between the jaws.
    h_fmin_columns: np.ndarray | None = None

    @property
    def area_total(self) -> np.ndarray:
        """A_T = sum_i A_i, the ranking heuristic (Sec. 6.2)."""
        return self.areas.sum(axis=1)

    @property
    def diameter_ok(self) -> np.ndarray:
        return self.h0 >= self.h_fmin - LENGTH_TOL

    @property
    def diameter_ok_columns(self) -> np.ndarray:
        """The frictional diameter condition (an extension): h0 >= h_fmin_columns.

        The paper's h_fmin sums every group object's d_fmin: frictionless jaws let the
        objects slide along the plates until they line up in one row between them. With
        friction at the plates (mu 0.5 here), an object pinched stays where it is across
        them: objects side by side across the plates' width each stand between the jaws in
        their own column, held by jaw friction. Assuming each column keeps its objects (no
        object slides from one column to another) and lines them up between the jaws, the
        jaws stop no narrower than the widest column: h_f >= max over columns of the
        column's summed d_fmin, and since the jaws only close, h0 >= h_f. Necessary under
        these assumptions, not for a frictionless grasp; where every object overlaps every
        other across the plates there is one column and it is the paper's condition."""
        if self.h_fmin_columns is None:
            raise ValueError("evaluate_grasps(..., columns=True) computes h_fmin_columns")
        return self.h0 >= self.h_fmin_columns - LENGTH_TOL

    @property
    def passed_columns(self) -> np.ndarray:
        """`passed` with the frictional diameter condition in place of the paper's."""
        return self.collision_free & self.diameter_ok_columns & self.area_ok

    @property
    def area_ok(self) -> np.ndarray:
        return np.all(self.areas > AREA_EPS, axis=1)

    @property
    def passed(self) -> np.ndarray:
        """Collision-free and not GraspFailure(): both necessary conditions hold."""
        return self.collision_free & self.diameter_ok & self.area_ok

    def __len__(self) -> int:
        return len(self.grasps)

    def subset(self, idx) -> GraspEvaluation:
        idx = np.asarray(idx)
        return GraspEvaluation(
            grasps=self.grasps[idx],
            group=self.group,
            areas=self.areas[idx],
            h0=self.h0[idx],
            b_l=self.b_l[idx],
            b_r=self.b_r[idx],
            h_fmin=self.h_fmin,
            collision_free=self.collision_free[idx],
            in_s=self.in_s[idx],
            h_fmin_columns=None if self.h_fmin_columns is None else self.h_fmin_columns[idx],
        )

    def verdict(self, i: int) -> str:
        """One word for candidate i: collision, diameter, area (first failed check) or passed."""
        if not self.collision_free[i]:
            return "collision"
        if not self.diameter_ok[i]:
            return "diameter"
        if not self.area_ok[i]:
            return "area"
        return "passed"

    def record(self, i: int) -> dict:
        """JSON-ready figures of candidate i (SI units)."""
        extra = [int(j) for j in np.flatnonzero(self.in_s[i]) if j not in set(self.group.tolist())]
        return {
            "grasp": [float(v) for v in self.grasps[i]],
            "h0": float(self.h0[i]),
            "h_fmin": float(self.h_fmin),
            "b_l": None if np.isnan(self.b_l[i]) else float(self.b_l[i]),
            "b_r": None if np.isnan(self.b_r[i]) else float(self.b_r[i]),
            "areas": {int(g): float(a) for g, a in zip(self.group, self.areas[i])},
            "area_total": float(self.area_total[i]),
            "collision_free": bool(self.collision_free[i]),
            "diameter_ok": bool(self.diameter_ok[i]),
            "area_ok": bool(self.area_ok[i]),
            "other_objects_in_S": extra,
            "verdict": self.verdict(i),
        }


def _near_pairs(polys: PolygonSet, grasps: np.ndarray, gripper: GripperGeometry):
    """(grasp, object) pairs that can touch S or a jaw, with the objects in grasp frames and
    the x-range of their part inside the strip |y| <= plate_width/2 (shared by S and jaws)."""
    hw, hy, t = gripper.w_g / 2, gripper.plate_width / 2, gripper.plate_thickness
    # Object centres in every grasp frame: keep pairs whose bounding circle reaches the box
    # spanned by both jaws.
    ctr = to_grasp_frame(polys.centers[None, :, None, :], grasps[:, None, :])[:, :, 0, :]
    r = polys.radii[None, :]
    bi, mi = np.nonzero((np.abs(ctr[..., 0]) < r + hw + t) & (np.abs(ctr[..., 1]) < r + hy))
    P = to_grasp_frame(polys.vertices[mi], grasps[bi])
    xlo, xhi, has = strip_extent(P, -hy, hy)

    def overlaps(lo: float, hi: float) -> np.ndarray:
        # A convex polygon with area in the strip meets a box of the strip with area iff
        # their x-ranges overlap with positive length.
        return has & (np.minimum(xhi, hi) - np.maximum(xlo, lo) > LENGTH_TOL)

    hits_jaw = overlaps(-hw - t, -hw) | overlaps(hw, hw + t)
    return bi, mi, P, xlo, xhi, hits_jaw, overlaps(-hw, hw)


def jaws_clear(
    polys: PolygonSet, worlds: int, group, grasp, gripper: GripperGeometry | None = None
) -> np.ndarray:
    """(W,) for ``polys`` holding ``worlds`` copies of one scene's M objects, world after
    world (W*M polygons, each world its own poses), and one grasp: True where its open jaws
    overlap no object of that world and every ``group`` object (indices within a world) has
    material inside S. `evaluate_grasps`' collision_free & area_ok, for many worlds at once."""
    gripper = gripper or GripperGeometry()
    g = np.asarray(grasp, dtype=float)[None, :]
    _, mi, P, _, _, hits_jaw, in_s_pair = _near_pairs(polys, g, gripper)
    M = len(polys) // worlds
    ok = np.ones(worlds, dtype=bool)
    ok[mi[hits_jaw] // M] = False
    member = np.zeros(M, dtype=bool)
    member[np.asarray(group, dtype=int)] = True
    need = in_s_pair & member[mi % M]
    area = np.zeros(len(polys))
    area[mi[need]] = box_intersection_area(P[need], gripper.boxes()["S"])
    return ok & (area.reshape(worlds, M)[:, group] > AREA_EPS).all(axis=1)


def jaw_collision_free(polys: PolygonSet, grasps, gripper: GripperGeometry | None = None) -> np.ndarray:
    """(B,) True where neither jaw overlaps any object (touching is allowed)."""
    gripper = gripper or GripperGeometry()
    grasps = np.atleast_2d(np.asarray(grasps, dtype=float))
    bi, _, _, _, _, hits_jaw, _ = _near_pairs(polys, grasps, gripper)
    collision = np.zeros(len(grasps), dtype=bool)
    collision[bi[hits_jaw]] = True
    return ~collision


def evaluate_grasps(
    polys: PolygonSet, group, grasps, gripper: GripperGeometry | None = None, columns: bool = False
) -> GraspEvaluation:
    """Evaluates grasps (B, 3) on ``group`` against every object of ``polys``, vectorized;
    with ``columns``, also the frictional diameter condition's h_fmin_columns (about a third
    more time)."""
    gripper = gripper or GripperGeometry()
    grasps = np.atleast_2d(np.asarray(grasps, dtype=float))
    group = np.asarray(group, dtype=int)
    B, M = len(grasps), len(polys)
    hw = gripper.w_g / 2
    bi, mi, P, xlo, xhi, hits_jaw, in_s_pair = _near_pairs(polys, grasps, gripper)

    collision = np.zeros(B, dtype=bool)
    collision[bi[hits_jaw]] = True
    in_s = np.zeros((B, M), dtype=bool)
    in_s[bi[in_s_pair], mi[in_s_pair]] = True
    lo_full = np.full((B, M), np.inf)
    hi_full = np.full((B, M), -np.inf)
    lo_full[bi[in_s_pair], mi[in_s_pair]] = np.maximum(xlo[in_s_pair], -hw)
    hi_full[bi[in_s_pair], mi[in_s_pair]] = np.minimum(xhi[in_s_pair], hw)

    # A_i = Area(S ∩ O_i), computed only for group objects that reach S.
    member = np.zeros(M, dtype=bool)
    member[group] = True
    need = in_s_pair & member[mi]
    area_full = np.zeros((B, M))
    area_full[bi[need], mi[need]] = box_intersection_area(P[need], gripper.boxes()["S"])

    any_s = in_s.any(axis=1)
    ext_lo, ext_hi = lo_full.min(axis=1), hi_full.max(axis=1)
    b_l = np.where(any_s, ext_lo + hw, np.nan)
    b_r = np.where(any_s, hw - ext_hi, np.nan)
    h0 = np.where(any_s, gripper.w_g - (np.nan_to_num(b_l) + np.nan_to_num(b_r)), 0.0)
    return GraspEvaluation(
        grasps=grasps,
        group=group,
        areas=area_full[:, group],
        h0=h0,
        b_l=b_l,
        b_r=b_r,
        h_fmin=float(polys.d_fmin[group].sum()),
        collision_free=~collision,
        in_s=in_s,
        h_fmin_columns=_columns(polys, group, P, bi, mi, need, gripper=gripper, B=B) if columns else None,
    )


def _columns(polys, group, P, bi, mi, need, *, gripper, B) -> np.ndarray:
    """h_fmin_columns of each of B grasps: each group object's extent across the plates (y)
    within S; the group's objects swept in order of that extent's start, overlapping ones
    summed into a column; the largest sum kept."""
    hw, M = gripper.w_g / 2, len(polys)
    hy = gripper.plate_width / 2
    ylo, yhi, has_y = strip_extent(P[need][..., ::-1], -hw, hw)
    pos = np.full(M, -1)
    pos[group] = np.arange(len(group))
    lo = np.full((B, len(group)), np.inf)
    hi = np.full((B, len(group)), np.inf)
    ok_y = has_y & (np.minimum(yhi, hy) - np.maximum(ylo, -hy) > LENGTH_TOL)
    lo[bi[need][ok_y], pos[mi[need][ok_y]]] = np.maximum(ylo[ok_y], -hy)
    hi[bi[need][ok_y], pos[mi[need][ok_y]]] = np.minimum(yhi[ok_y], hy)
    order = np.argsort(lo, axis=1)
    lo, hi = np.take_along_axis(lo, order, 1), np.take_along_axis(hi, order, 1)
    d = polys.d_fmin[group][order]
    best = np.zeros(B)
    run = np.zeros(B)
    end = np.full(B, -np.inf)
    for k in range(len(group)):
        real = np.isfinite(lo[:, k])
        same = real & (lo[:, k] < end - LENGTH_TOL)
        run = np.where(same, run + d[:, k], np.where(real, d[:, k], run))
        end = np.where(same, np.maximum(end, hi[:, k]), np.where(real, hi[:, k], end))
        best = np.maximum(best, run)
    return best


def grasp_failure(ev: GraspEvaluation) -> np.ndarray:
    """GraspFailure() of Alg. 2: True where a necessary condition is violated (Eq. 7 or 9)."""
    return ~(ev.diameter_ok & ev.area_ok)
