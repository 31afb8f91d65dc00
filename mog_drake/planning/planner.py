"""GraspPlanner: Alg. 2 of the paper and its baselines (Sec. 6.2, 7.3). No Drake import.

    grasp_cands <- GenGraspCands(x, group)
    ranked      <- RankGraspCands(grasp_cands)
    for u in ranked:
        if not GraspFailure(x, u):            # the two necessary conditions
            if CheckGraspSuccess(x, u):       # physics, through the Verifier protocol
                return u
    return {}

Methods, exactly as the paper defines them:

* ``gp``: rank by total intersection area A_T, filter by the conditions, then physics;
* ``rand-phys``: random order, no filter: physics on every candidate until one succeeds;
* ``rank-phys``: ranked order, no filter;
* ``rand-fil-phys``: random order, filter, then physics;
* ``single``: the single-object baseline: ``gp`` on one object of the group chosen at random.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from mog_drake.errors import MogError
from mog_drake.geometry import (
    GripperGeometry,
    PolygonSet,
    evaluate_grasps,
    gen_grasp_cands,
    jaw_collision_free,
    rank_grasp_cands,
)
from mog_drake.geometry.gripper import clear_of_boxes
from mog_drake.geometry.polygon import axis_gap, squeeze_basins, transform
from mog_drake.planning.config import LARGE_GROUP, METHODS, GraspConfig
from mog_drake.planning.protocol import GraspResult, Verifier

_RANKED = {"gp": True, "rand-phys": False, "rank-phys": True, "rand-fil-phys": False, "single": True}
_FILTERED = {"gp": True, "rand-phys": False, "rank-phys": False, "rand-fil-phys": True, "single": True}


def draws_at_random(method: str) -> bool:
    """Whether ``method`` draws at random (its candidates' order, or the object): else a
    plan of the same scene and group gives the same verdict every time."""
    return not _RANKED[method] or method == "single"


def _method_and_group(method: str, group, rng) -> tuple[str, tuple[int, ...]]:
    """A plan's method, checked, and the objects it grasps: ``group``, or for ``single`` one
    of them drawn with ``rng``."""
    if method not in METHODS:
        raise MogError(f"unknown planner method '{method}' (known: {', '.join(METHODS)})")
    group = tuple(int(g) for g in group)
    if not group:
        raise MogError("the group to grasp is empty")
    if draws_at_random(method) and rng is None:
        raise MogError(f"method '{method}' draws at random: pass a seeded numpy Generator")
    if method == "single":
        group = (group[int(rng.integers(len(group)))],)
    return method, group


def repeats(grasps, avoid) -> np.ndarray:
    """Which of ``grasps`` (N, 3) repeat one of ``avoid`` (M, 3): within 5 mm and 0.15 rad
    (closing axes modulo pi)."""
    g = np.asarray(grasps, dtype=float).reshape(-1, 3)
    a = np.asarray(avoid, dtype=float).reshape(-1, 3)
    if not len(a):
        return np.zeros(len(g), dtype=bool)
    near = np.linalg.norm(g[:, None, :2] - a[None, :, :2], axis=2) < 0.005
    return np.any(near & (axis_gap(g[:, None, 2], a[None, :, 2]) < 0.15), axis=1)


@dataclass
class PlanResult:
    """What GraspPlanner.plan returns. ``grasp`` is None when no candidate succeeded."""

    method: str
    group: tuple[int, ...]
    grasp: np.ndarray | None
    candidates: int  # collision-free candidates generated
    passed_conditions: int  # of those, how many pass both conditions (computed when filtering or ranking)
    tested: int  # candidates simulated in physics
    times: dict[str, float] = field(default_factory=dict)  # candidates, filter, rank, physics, total (s)
    result: GraspResult | None = None  # physics result of the returned grasp (or the last tested)
    tested_indices: list[int] = field(default_factory=list)  # candidate indices in the order simulated
    candidate_grasps: np.ndarray | None = None
    # The tested candidate that lifted the most objects without an error, even if not the
    # whole group: (grasp, lifted ids). A verified grasp of those objects.
    best_lift: tuple[np.ndarray, list[int]] | None = None
    # A grasp the last resort found (`picking._last_resort`): "relaxed" (its relaxed screen) or
    # "nominal" (the nominal check alone); "" for the planner's own check. Kept in a
    # remembered plan, so a replayed grasp is still known for what it is.
    found_by: str = ""
    # The tested candidates a robust check refused for want of robustness alone
    # (`GraspResult.not_robust`), which the last resort's nominal pass checks again.
    not_robust: list[int] = field(default_factory=list)

    @property
    def found(self) -> bool:
        return self.grasp is not None

    def text(self) -> str:
        t = self.times
        g = self.grasp
        return "\n".join(
            [
                f"method     {self.method}   group {list(self.group)}",
                f"candidates {self.candidates} collision-free"
                + (f", {self.passed_conditions} pass both conditions" if self.passed_conditions >= 0 else ""),
                f"tested     {self.tested} in physics",
                "grasp      "
                + (
                    "none found"
                    if g is None
                    else f"x={g[0] * 1e3:.2f} mm  y={g[1] * 1e3:.2f} mm  theta={math.degrees(g[2]):.2f} deg   lifted {self.result.lifted}"
                ),
                f"time       {t['total']:.3f} s (candidates {t['candidates'] * 1e3:.1f} ms, filter {t['filter'] * 1e3:.1f} ms, "
                f"rank {t['rank'] * 1e3:.1f} ms, physics {t['physics']:.3f} s)",
            ]
        )

    def to_dict(self) -> dict:
        return {
            "method": self.method,
            "group": list(self.group),
            "found": self.found,
            "grasp": None if self.grasp is None else [float(v) for v in self.grasp],
            "candidates": self.candidates,
            "passed_conditions": self.passed_conditions,
            "tested": self.tested,
            "times": self.times,
            "lifted": None if self.result is None else self.result.lifted,
            "physics_error": None if self.result is None else self.result.error,
        }


class GraspPlanner:
    """Alg. 2 and its baselines over any `Verifier` (the Drake one, or a test double)."""

    def __init__(
        self,
        verifier: Verifier,
        config: GraspConfig | None = None,
        gripper: GripperGeometry | None = None,
        keep_out=(),
    ):
        self.verifier = verifier
        self.config = config or GraspConfig()
        self.gripper = gripper or GripperGeometry()
        # Regions of the table (xmin, xmax, ymin, ymax) the open jaws must not enter: the
        # cell's fixtures (the bin), which the physics check does not model.
        self.keep_out = tuple(tuple(float(v) for v in box) for box in keep_out)
        for box in self.keep_out:
            if len(box) != 4 or not (box[0] < box[1] and box[2] < box[3]):
                raise MogError(
                    f"a keep-out region must be (xmin, xmax, ymin, ymax) with min < max, got {box}"
                )

    def plan(
        self,
        scene,
        group,
        rng: np.random.Generator | None = None,
        method: str | None = None,
        avoid=(),
        skip=(),
        *,
        alone: bool = False,
    ) -> PlanResult:
        """``avoid``: grasps (x, y, theta) not to try again; candidates within 5 mm and 0.15 rad
        (modulo pi: the jaws are symmetric) of one are skipped. ``skip``: candidate indices an
        earlier plan of the same scene and group already simulated (its ``tested_indices``):
        not simulated again, and their closing axes count as tried (``vary_axis``), so the plan
        goes on where the earlier one stopped. ``alone``: a check that lifts any object beyond
        the group is no success (`LoopConfig.sog_alone`)."""
        method, group = _method_and_group(method or self.config.method, group, rng)
        cfg = self.config
        t_start = time.perf_counter()
        polys = scene.polygons()

        t = time.perf_counter()
        cands, margin, final = self._candidates(polys, group, jaw_obstacles(scene, group))
        times = {"candidates": time.perf_counter() - t, "filter": 0.0, "rank": 0.0, "physics": 0.0}

        passed = None
        n_passed = -1
        if _RANKED[method] or _FILTERED[method]:
            t = time.perf_counter()
            ev = evaluate_grasps(
                polys, group, cands, self.gripper, columns=cfg.diameter_condition == "columns"
            )
            passed = ev.passed if cfg.diameter_condition == "paper" else ev.passed_columns
            n_passed = int(passed.sum())
            times["filter" if _FILTERED[method] else "rank"] += time.perf_counter() - t
        if _RANKED[method]:
            t = time.perf_counter()
            order = rank_grasp_cands(ev)
            if cfg.lone_widest_basin and margin is not None:
                # widest basin (to 0.5 deg), then nearest its final axis (to 5 deg), then
                # nearest the object's centre (to 2 mm), then area
                turn = np.round(axis_gap(cands[order, 2], final[order]) / math.radians(5))
                widest = -np.round(margin[order] / math.radians(0.5))
                off = np.round(np.linalg.norm(cands[order, :2] - polys.centers[group[0]], axis=1) / 0.002)
                order = order[np.lexsort((off, turn, widest))]
            times["rank"] += time.perf_counter() - t
        else:
            order = rng.permutation(len(cands))
        if _FILTERED[method]:
            t = time.perf_counter()
            order = order[passed[order]]  # GraspFailure(): drop candidates violating a condition
            times["filter"] += time.perf_counter() - t
        if len(avoid) and len(cands):
            order = order[~repeats(cands, avoid)[order]]
        skip = [int(i) for i in skip if 0 <= int(i) < len(cands)]
        if skip:
            order = order[~np.isin(order, skip)]

        cap = cfg.max_physics
        if cfg.max_physics_large is not None and len(group) >= LARGE_GROUP:
            cap = cfg.max_physics_large if cap is None else min(cap, cfg.max_physics_large)
        grasp, last, tested, not_robust, best_lift = None, None, [], [], None
        t = time.perf_counter()
        for i in self._test_order(order, cands, cfg.vary_axis, [float(cands[j, 2]) for j in skip]):
            if cap is not None and len(tested) >= cap:
                break
            last = self.verifier.check(scene, group, cands[i])
            tested.append(int(i))
            if last.not_robust:
                not_robust.append(int(i))
            held = last.complete and not last.error and last.lifted
            if held and (best_lift is None or len(last.lifted) > len(best_lift[1])):
                best_lift = (cands[i].copy(), sorted(int(k) for k in last.lifted))
            if last.success and not (alone and set(last.lifted) - set(group)):
                grasp = cands[i].copy()
                break
        times["physics"] = time.perf_counter() - t
        times["total"] = time.perf_counter() - t_start
        return PlanResult(
            method,
            group,
            grasp,
            len(cands),
            n_passed,
            len(tested),
            times,
            last,
            tested,
            cands,
            best_lift,
            not_robust=not_robust,
        )

    def _candidates(self, polys, group, blobs=None):
        """The candidates of ``group`` (Sec. 5.1) clear of the keep-out boxes and with their
        open jaws off ``blobs`` (`jaw_obstacles`); for a lone object with squeeze basins in
        use, only those whose basin is wide enough, with each basin's width and final axis
        (else None, None)."""
        cfg = self.config
        cands = gen_grasp_cands(
            polys, group, self.gripper, cfg.n_positions, cfg.n_orientations, cfg.edge_orientations
        )
        if self.keep_out and len(cands):
            cands = cands[clear_of_boxes(cands, self.keep_out, self.gripper)]
        if blobs is not None and len(cands):
            cands = cands[jaw_collision_free(blobs, cands, self.gripper)]
        margin = final = None
        if (cfg.min_squeeze_margin_deg > 0 or cfg.lone_widest_basin) and len(group) == 1 and len(cands):
            final, margin = squeeze_basins(polys.polygon(group[0]), cands[:, 2])
            keep = margin >= math.radians(cfg.min_squeeze_margin_deg)
            cands, margin, final = cands[keep], margin[keep], final[keep]
        return cands, margin, final

    AXIS_TOL = 0.15  # rad, closing axes this close (modulo pi) count as one axis

    @classmethod
    def _test_order(cls, order, cands, vary_axis: bool, tried=()):
        """Yields candidate indices in ``order``; with ``vary_axis``, each one after a failure
        (or ``tried``: axes already tried) is the first whose axis is not within AXIS_TOL of an
        axis already tried (falling back to ``order`` once every remaining axis was tried).
        The caller stops at a success."""
        if not vary_axis:
            yield from order
            return
        left = [int(i) for i in order]
        tried = [float(a) for a in tried]
        while left:
            k = 0
            if tried:
                gaps = axis_gap(cands[left, 2][:, None], np.asarray(tried)[None, :]).min(axis=1)
                fresh = np.flatnonzero(gaps >= cls.AXIS_TOL)
                k = int(fresh[0]) if len(fresh) else 0
            i = left.pop(k)
            tried.append(float(cands[i, 2]))
            yield i


def jaw_obstacles(scene, group=()) -> PolygonSet | None:
    """What the open jaws of a grasp of ``group`` must not come down on besides the scene's
    objects, from ``scene.meta``, as a PolygonSet for the jaws' collision check (None when
    nothing):

    * ``unrecognised``: the outlines of the blobs perception saw but could not fit (each the
      convex hull of its points seen from above: a knocked-over or leaning prism is under a
      jaw as surely as an object);
    * ``missed_jaws``: the footprints of the jaws of recent grasps that took none of their
      objects (`jaw_footprints`): what stopped or pushed them there may still be there,
      seen or not, and a grasp shifted by a few millimetres would meet it again;
    * ``wary``: objects a missed grasp's jaws may have come down on, each outline grown by
      its margin (`picking.wary_outlines`), except those of ``group``'s own objects."""
    outlines = [np.asarray(b["vertices"], dtype=float) for b in scene.meta.get("unrecognised", ())]
    outlines += [np.asarray(v, dtype=float) for v in scene.meta.get("missed_jaws", ())]
    members = [scene.objects[int(i)] for i in group]
    outlines += [
        np.asarray(w["vertices"], dtype=float)
        for w in scene.meta.get("wary", ())
        if not any(o.shape == w["shape"] and math.hypot(o.x - w["x"], o.y - w["y"]) < 1e-6 for o in members)
    ]
    outlines = [v for v in outlines if len(v) >= 3]
    if not outlines:
        return None
    n = max(len(v) for v in outlines)
    centers = np.array([v.mean(axis=0) for v in outlines])
    return PolygonSet(
        vertices=np.array([np.vstack([v, np.repeat(v[-1:], n - len(v), axis=0)]) for v in outlines]),
        counts=np.array([len(v) for v in outlines]),
        centers=centers,
        radii=np.array([np.linalg.norm(v - c, axis=1).max() for v, c in zip(outlines, centers)]),
        d_fmin=np.zeros(len(outlines)),
    )


def jaw_footprints(grasp, gripper: GripperGeometry | None = None) -> list[list[list[float]]]:
    """The two open jaws' rectangles of ``grasp`` (x, y, theta) on the table, CCW corners."""
    gripper = gripper or GripperGeometry()
    out = []
    for name in ("left_jaw", "right_jaw"):
        x0, x1, y0, y1 = gripper.boxes()[name]
        out.append(transform([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], *(float(v) for v in grasp)).tolist())
    return out
