"""push-mog's pushes inside a decision (an extension of Alg. 1): which pushes bring a lone
object next to another so that one grasp takes both, checked in physics; a push remembered
to have paid is replayed, one that did not is skipped while its objects lie still."""

from __future__ import annotations

import copy
import time
from dataclasses import replace

import numpy as np

from mog_drake.errors import MogError
from mog_drake.geometry import ranked_groups
from mog_drake.geometry.push import Push, push_candidates, push_duration
from mog_drake.planning.config import PlannerSpec
from mog_drake.planning.decision import (
    MEMORY_SIZE,
    MEMORY_TOL,
    FailedPush,
    PaidPush,
    PickDecision,
    around_group,
    same_group,
)
from mog_drake.planning.planner import GraspPlanner, repeats

# push-mog: physics checks for the grasp a simulated push sets up (its first candidates lift
# it if any does: the push made the group compact).
PUSH_GRASP_CHECKS = 2


def paid_push(before, d: PickDecision, gripper) -> PaidPush | None:
    """Push decision ``d`` on ``before`` as a `PaidPush`; None if its grasp does not follow at
    once (nothing to replay) or the simulated push moved an object beyond its group's reach
    (its replay would miss that)."""
    if d.grasp is None or d.after is None or len(d.after.objects) != len(before.objects):
        return None
    around = around_group(before, d.group, gripper)
    inside = {i for i, _, _ in around}
    for i in range(len(before.objects)):
        if i not in inside:
            if np.abs(before.polygon(i) - d.after.polygon(i)).max() > MEMORY_TOL:
                return None
    after = tuple((i, d.after.objects[i]) for i in sorted(inside))
    return PaidPush(d.push, tuple(d.group), around, tuple(d.expected), np.asarray(d.grasp), after)


def _same_push(
    target: int, toward: int, f_group, f_around, p: Push, group, *, around
) -> dict[int, int] | None:
    """Old id -> new id if a remembered push (of ``target`` to ``toward``, setting up
    ``f_group``, with ``f_around`` around it) is push ``p`` of ``group`` now, every object
    around it where it was (``around``, now); else None."""
    ids = same_group(f_group, f_around, group, around)
    if ids is None or ids.get(target) != p.target or ids.get(toward) != p.toward:
        return None
    return ids


def _replay_push(known, p: Push, group, around, scene, avoid):
    """The remembered `PaidPush` of push ``p`` of ``group`` (same objects, each where it
    was) in ``scene``'s ids: (its entry, the push, what its grasp lifted, the grasp, the table
    it leaves); None if there is none, or its grasp repeats one to avoid."""
    for f in known:
        ids = _same_push(f.push.target, f.push.toward, f.group, f.around, p, group, around=around)
        if ids is None:
            continue
        if repeats([f.grasp], avoid)[0]:
            return None
        objects = list(scene.objects)
        for i, o in f.after:
            objects[ids[i]] = o
        lifted = tuple(ids[i] for i in f.lifted if i in ids)
        push = replace(f.push, target=p.target, toward=p.toward)
        return f, push, lifted, f.grasp, replace(scene, objects=objects)
    return None


def consider_pushes(
    scene, planner: GraspPlanner, spec: PlannerSpec, d: PickDecision, rng, avoid, *, memory=None
) -> None:
    """push-mog: turns decision ``d`` (Alg. 1's) into a push when its grasp lifts fewer than
    ``pushes.below`` objects and the push and the grasp it sets up are expected to take more
    objects per second of robot time than ``d``'s grasp:
    m / (push_time_s + T + grasp_time_s) > n / grasp_time_s, n being what ``d``'s grasp
    lifted in the physics check, m what the grasp after the push lifted, and T the push's
    own time along its line (`push_duration`).

    Candidates (`push_candidates`): an object pushed along the line of centres to another one,
    joining the largest group (of Alg. 1's, on this table) that holds the other one and not
    it, and fits the jaws. Those whose group is large enough to beat ``d`` by that rule, even
    if the grasp lifts it all, are simulated largest group first, then shortest push, up to
    ``pushes.checks`` of them: the push in physics (the verifier's ``push``), then the group's
    grasp planned on the table the push leaves (the same planner, physics included).

    ``memory`` (the previous decision's, with remember_failures; None: off): a push that did
    not pay before (`FailedPush`), whose surroundings are where they were, is not simulated
    again and does not count against ``pushes.checks``: the next candidate is simulated
    instead. Pushes that do not pay now are added to ``d.failures``. A push the lookahead
    found to pay (`PaidPush`), whose objects are where they were, is taken with its grasp and
    nothing is simulated."""
    t0 = time.perf_counter()
    verifier = planner.verifier
    if not hasattr(verifier, "push"):
        raise MogError("push-mog needs a verifier that simulates pushes (DrakeVerifier)")
    n_now = len(d.expected) if d.status == "grasp" else 0
    if n_now >= spec.pushes.below:
        return
    tp, tg = spec.pushes.push_time_s, spec.pushes.grasp_time_s
    options = _push_options(scene, planner, spec, n_now)
    best, checks, simulated, failed = None, 0, 0, []
    known = [f for f in memory or () if isinstance(f, FailedPush)]
    paid = [f for f in memory or () if isinstance(f, PaidPush)]
    for _, _, p, group in options if paid else ():  # the lookahead's push, if it stands
        hit = _replay_push(paid, p, group, around_group(scene, group, planner.gripper), scene, avoid)
        if (
            hit is not None
            and len(hit[2]) / (tp + push_duration(hit[1], spec.pushes.speed) + tg) > n_now / tg
        ):
            used, push, lifted, grasp, after = hit
            best = (push, lifted, group, grasp, after)
            d.remembered_pushes += 1
            d.failures = tuple(f for f in d.failures if f is not used)
            options = []  # nothing to simulate
            break
    quick = copy.copy(planner)  # the grasps a push sets up: PUSH_GRASP_CHECKS checks each
    quick.config = replace(planner.config, max_physics=PUSH_GRASP_CHECKS)
    for _, _, p, group in options:
        if simulated >= spec.pushes.checks:
            break
        around = around_group(scene, group, planner.gripper) if memory is not None else ()
        if memory is not None and _did_not_pay(
            known, p, group, around, n_now / tg, tp + push_duration(p, spec.pushes.speed) + tg
        ):
            d.remembered_pushes += 1
            continue
        simulated += 1
        r = verifier.push(scene, p, spec.pushes.speed)
        if r.error:
            failed.append(FailedPush(p.target, p.toward, group, around, 0))
            continue
        res = quick.plan(r.scene, group, rng=rng, avoid=avoid)
        checks += res.tested
        if res.found:
            grasp, lifted = res.grasp, tuple(res.result.lifted)
        elif res.best_lift is not None:
            grasp, lifted = res.best_lift[0], tuple(res.best_lift[1])
        else:
            failed.append(FailedPush(p.target, p.toward, group, around, 0))
            continue
        rate = len(lifted) / (tp + push_duration(p, spec.pushes.speed) + tg)
        if rate <= n_now / tg:
            failed.append(FailedPush(p.target, p.toward, group, around, len(lifted)))
        elif best is None or len(lifted) > len(best[1]):
            best = (p, lifted, group, grasp, r.scene)
            if len(lifted) >= len(group):  # the largest group first: none to come lifts more
                break
    d.physics_checks += checks
    if memory is not None and failed:
        d.failures = (tuple(failed) + tuple(d.failures))[:MEMORY_SIZE]
    if best is not None:
        d.now, d.push = n_now, best[0]
        d.status, d.group, d.expected = "push", best[2], best[1]
        d.grasp = best[3] if spec.pushes.then_grasp else None
        d.after = best[4]
        d.shapes = tuple(scene.objects[i].shape for i in d.group)
        d.partial = d.last_resort = False
    d.planning_time += time.perf_counter() - t0


def _push_options(scene, planner: GraspPlanner, spec: PlannerSpec, n_now: int) -> list[tuple]:
    """The pushes worth simulating (see `consider_pushes`), largest group first, then
    shortest push: (-len(group), distance, push, group)."""
    tp, tg = spec.pushes.push_time_s, spec.pushes.grasp_time_s
    polys = scene.polygons()
    groups = ranked_groups(polys, planner.gripper, spec.loop.grouping, spec.loop.group_radius)
    w_g = planner.gripper.w_g
    options = []
    for p in push_candidates(polys, range(len(scene)), planner.gripper, spec.pushes.reach, planner.keep_out):
        joined = next((g for g in groups if p.toward in g and p.target not in g), (p.toward,))
        group = tuple(sorted((p.target, *joined)))
        if polys.d_fmin[list(group)].sum() > w_g:
            continue
        if len(group) / (tp + push_duration(p, spec.pushes.speed) + tg) > n_now / tg:
            options.append((-len(group), p.distance, p, group))
    options.sort(key=lambda o: o[:2])
    return options


LONE_REASONS = ("too far", "blocked", "not worth it", "out of pushes")


def lone_reason(scene, planner: GraspPlanner, spec: PlannerSpec, d: PickDecision, pushes_left: int) -> str:
    """push-mog: why decision ``d``, a grasp of one object, was not a push that set up more:
    "out of pushes" (none left for this table), "too far" (no other object within
    ``pushes.reach``), "blocked" (others within reach, but no push between it and any of
    them keeps the jaws clear of the objects and of the bin), or "not worth it" (pushes
    exist, and none was expected to pay, or none paid in physics). "" for any other decision."""
    if d.status != "grasp" or d.unrecognised or len(d.expected) > 1 or len(d.group) != 1:
        return ""
    if pushes_left <= 0 or spec.pushes.checks <= 0:
        return "out of pushes"
    i = d.group[0]
    polys = scene.polygons()
    dist = np.linalg.norm(polys.centers - polys.centers[i], axis=1)
    if not np.any((dist > 0) & (dist <= spec.pushes.reach)):
        return "too far"
    pushes = push_candidates(polys, range(len(scene)), planner.gripper, spec.pushes.reach, planner.keep_out)
    return "not worth it" if any(i in (p.target, p.toward) for p in pushes) else "blocked"


def _did_not_pay(known, p, group, around, now_rate: float, push_time: float) -> bool:
    """Whether push ``p`` of ``group`` is a remembered `FailedPush` (same objects, each where
    it was) that would not pay now either: it failed, or what its grasp lifted over
    ``push_time`` does not beat ``now_rate`` (objects per second of the grasp now)."""
    for f in known:
        if _same_push(f.target, f.toward, f.group, f.around, p, group, around=around) is not None:
            return f.lifted == 0 or f.lifted / push_time <= now_rate
    return False
