"""One step of the picking algorithm (paper Alg. 1, Sec. 6.1), and its single-object baseline.

    obj_groups        <- CreateObjGroups(x)
    ranked_obj_groups <- RankObjGroups(obj_groups)
    for obj_group in ranked_obj_groups:
        u <- GraspPlanner(x, obj_group)
        if u != {}: execute u; break

The outer loop (observe, execute, repeat until the table is clear or time is up) is the
Planner and Controller systems' job; this module decides the next grasp for one observation.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from mog_drake.errors import MogError
from mog_drake.geometry import DEFAULT_GROUP_RADIUS, create_obj_groups, rank_obj_groups
from mog_drake.planning.planner import GraspPlanner, PlanResult

MODES = ("mog", "sog")


@dataclass
class PickDecision:
    """status: "grasp" (grasp and group set), "table_clear", "no_grasp", or "unrecognised" (no
    library object is left but perception sees something it cannot recognise)."""

    status: str
    grasp: np.ndarray | None = None
    group: tuple[int, ...] = ()
    groups_tried: int = 0
    partial: bool = False  # the grasp lifted part of a larger group it was planned for
    expected: tuple[int, ...] = ()  # objects the physics check lifted with this grasp
    physics_checks: int = 0
    planning_time: float = 0.0
    plans: list[PlanResult] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {
            "status": self.status,
            "grasp": None if self.grasp is None else [float(v) for v in self.grasp],
            "group": list(self.group),
            "groups_tried": self.groups_tried,
            "partial": self.partial,
            "expected": list(self.expected),
            "physics_checks": self.physics_checks,
            "planning_time": self.planning_time,
        }


def next_pick(
    scene,
    planner: GraspPlanner,
    mode: str = "mog",
    rng: np.random.Generator | None = None,
    group_radius: float = DEFAULT_GROUP_RADIUS,
    partial_lifts: bool = True,
    avoid=(),
) -> PickDecision:
    """The next grasp for the objects of ``scene``.

    mode "mog": Alg. 1, the largest groups first. mode "sog": the paper's single-object
    baseline, the same planner restricted to one object chosen at random (objects are tried
    in a random order until one has a grasp).

    partial_lifts (mog only; an extension of Alg. 1): a candidate that the physics check saw
    lift only k objects of a larger group is still a verified grasp of those k. Once every
    group left to try has at most k objects, that grasp is taken instead of planning them, and
    it is taken rather than giving up when no group succeeds.

    avoid: grasps not to try again (the robot's last few), so that a grasp the physics check
    trusts but the world keeps failing is not repeated attempt after attempt."""
    if mode not in MODES:
        raise MogError(f"picking mode must be one of {MODES}, got {mode!r}")
    t0 = time.perf_counter()
    if len(scene) == 0:
        # Something the perception could not recognise (a prism knocked onto its side) is not
        # a clear table.
        status = "unrecognised" if scene.meta.get("unrecognised_blobs", 0) else "table_clear"
        return PickDecision(status, planning_time=time.perf_counter() - t0)
    polys = scene.polygons()
    if mode == "mog":
        groups = rank_obj_groups(
            create_obj_groups(polys.centers, group_radius), polys.d_fmin, planner.gripper.w_g
        )
    else:
        if rng is None:
            raise MogError("single-object picking draws objects at random: pass a seeded numpy Generator")
        groups = [(int(i),) for i in rng.permutation(len(scene))]
    partial_lifts = partial_lifts and mode == "mog"
    decision = PickDecision("no_grasp")
    best = None  # (grasp, lifted ids) of the tested candidate that lifted the most objects
    for group in groups:
        if partial_lifts and best is not None and len(best[1]) >= len(group):
            break
        res = planner.plan(scene, group, rng=rng, avoid=avoid)
        decision.plans.append(res)
        decision.groups_tried += 1
        decision.physics_checks += res.tested
        if res.found:
            decision.status, decision.grasp, decision.group = "grasp", res.grasp, res.group
            decision.expected = tuple(res.result.lifted) if res.result is not None else res.group
            break
        if res.best_lift is not None and (best is None or len(res.best_lift[1]) > len(best[1])):
            best = res.best_lift
    if decision.status != "grasp" and partial_lifts and best is not None:
        decision.status, decision.grasp, decision.group = "grasp", best[0], tuple(best[1])
        decision.partial, decision.expected = True, tuple(best[1])
    decision.planning_time = time.perf_counter() - t0
    return decision
