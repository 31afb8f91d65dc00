"""One step of the picking algorithm (paper Alg. 1, Sec. 6.1), and its single-object baseline.

    obj_groups        <- CreateObjGroups(x)
    ranked_obj_groups <- RankObjGroups(obj_groups)
    for obj_group in ranked_obj_groups:
        u <- GraspPlanner(x, obj_group)
        if u != {}: execute u; break

The outer loop (observe, execute, repeat until the table is clear or time is up) is the
Planner and Controller systems' job; this module decides the next grasp for one observation.

Extensions of Alg. 1, each a `PlannerSpec` setting or an argument of `next_pick`:

* grouping "conditions": groups formed from the grasps that satisfy the necessary
  conditions (`condition_groups`) instead of CreateObjGroups' radius.
* partial lifts (mog): a candidate the physics check saw lift only k objects of a larger
  group is a verified grasp of those k. Once every group left has at most k objects it is
  taken instead of planning them, and rather than giving up when no group succeeds.
* avoid: the robot's last few grasps are not tried again, so a grasp the check trusts and
  the world keeps failing is not repeated attempt after attempt.
* failures (memory): a group found to have no grasp is not planned again while every object
  within its reach lies where it did; its remembered plan, partial lift included, stands in.
* last resort: when no group has a grasp within the planner's cap on physics checks, each is
  planned again with up to LAST_RESORT_CHECKS more (LAST_RESORT_TOTAL in all) before the
  decision gives up ("no_grasp"); a robust planner's check relaxed (`_last_resort`). With
  the memory on, its failures are remembered too, each by the pass that found it.
* unrecognised blobs: once no library object is left, what perception could not recognise
  (a prism knocked onto its side) is planned as prisms of its outline and top height
  (`unrecognised_scene`); without a grasp the status is "unrecognised".
* push-mog: grasps are planned for Alg. 1's groups and for groups of objects that meet within
  ADJACENT_GAP (a push leaves two bars end to end, farther apart than the group radius), and
  a push is taken when worth more (`mog_drake.planning.pushing`).
* exclude: no group holding an object given up on (`tally_misses`) is planned; when they are
  all that is left, the status is "gave_up".
"""

from __future__ import annotations

import copy
import hashlib
import time
from dataclasses import replace

import numpy as np
import shapely

from mog_drake.errors import MogError
from mog_drake.geometry import jaw_collision_free, ranked_groups
from mog_drake.geometry.groups import adjacent_groups
from mog_drake.geometry.polygon import polygon_area, polygon_centroid
from mog_drake.geometry.push import PUSH_GAP
from mog_drake.planning.config import MODES, PlannerSpec
from mog_drake.planning.decision import (
    MEMORY_SIZE,
    FailedGroup,
    FailedPush,
    PaidPush,
    PickDecision,
    around_group,
    drawn_first,
    recall,
)
from mog_drake.planning.planner import GraspPlanner, jaw_obstacles
from mog_drake.planning.pushing import consider_pushes, lone_reason
from mog_drake.scenes import Scene, SceneObject, make_shape

# Before a decision gives up ("no_grasp": the run would end with objects on the table), every
# group is planned again with this many more physics checks, going on where its capped plan
# stopped (an extension; see next_pick's ``last_resort``).
LAST_RESORT_CHECKS = 12
LAST_RESORT_TOTAL = 48  # physics checks at most over all groups
# An object the robot grasped this many times without taking it (it was still on the table
# within MISS_RADIUS of where it was, and the grasp took none of its targets) is given up
# on: a grasp that the physics check trusts and the world keeps failing (a pose perceived
# wrong, something the check does not model) would otherwise be tried until the time limit.
MAX_MISSES = 3
MISS_RADIUS = 0.03  # m: a failed grasp nudges its object; a taken one leaves nothing here
# LoopConfig.wary_neighbours: after a grasp that took none of its objects, the object nearest
# each of its open jaws, if its outline came within SUSPECT_NEAR of that jaw, may be what the
# plate came down on (its pose or size perceived wrong by at least that gap); later grasps keep
# their jaws that gap plus SUSPECT_EXTRA from it, until it is taken.
SUSPECT_NEAR = 0.008  # m: the deepest landings recorded at the paper's cell are 10 mm
SUSPECT_EXTRA = 0.002  # m: a plate stops on 1-2 mm of an object (docs/physics.md)
# push-mog: objects whose outlines come this close form a group too (a push leaves PUSH_GAP
# between them, and the pushed object may turn a little as it stops).
ADJACENT_GAP = PUSH_GAP + 0.004  # m


def next_pick(
    scene,
    planner: GraspPlanner,
    spec: PlannerSpec | None = None,
    rng: np.random.Generator | None = None,
    avoid=(),
    failures: tuple[FailedGroup | FailedPush | PaidPush, ...] | None = None,
    *,
    grasp_unrecognised: bool = True,
    pushes_left: int = 0,
    adjacent: float = 0.0,
    exclude=(),
) -> PickDecision:
    """The next grasp for the objects of ``scene``, as ``spec`` (`PlannerSpec`, its defaults
    when None) says, with the given grasp planner: mode "mog" is Alg. 1 (the largest groups
    first), "sog" the paper's single-object baseline (objects in a random order until one has
    a grasp), "push-mog" Alg. 1 or a consolidating push worth more (at most ``pushes_left``
    more). The extensions, each described in the module's docstring: ``avoid`` (grasps not
    to try again), ``failures`` (the previous decision's memory; None: off),
    ``grasp_unrecognised``, ``adjacent`` (push-mog's groups of objects that meet),
    ``exclude`` (objects given up on: `tally_misses`), and the spec's ``partial_lifts`` and
    ``last_resort``."""
    spec = spec or PlannerSpec()  # checked once, where it was loaded (PlannerSpec.check)
    if spec.mode == "push-mog":
        return _push_mog(
            scene,
            planner,
            spec,
            rng,
            avoid,
            failures,
            grasp_unrecognised=grasp_unrecognised,
            pushes_left=pushes_left,
            exclude=exclude,
        )
    mode, last_resort = spec.mode, spec.loop.last_resort
    t0 = time.perf_counter()
    if len(scene) == 0:
        return _blobs(
            scene, planner, spec, rng, avoid, failures, grasp_unrecognised=grasp_unrecognised, t0=t0
        )
    if mode == "mog":
        groups = _mog_groups(scene, planner, spec, adjacent)
    elif mode != "sog":
        raise MogError(f"planner.mode must be one of {', '.join(MODES)}, got {mode!r}")
    else:
        if rng is None:
            raise MogError("single-object picking draws objects at random: pass a seeded numpy Generator")
        groups = [(int(i),) for i in rng.permutation(len(scene))]
        if failures:  # the lookahead drew its object at random one image earlier: it goes first
            groups = drawn_first(groups, failures, scene)
    if len(exclude):
        groups = _excluding(groups, exclude)
        if not groups:
            return PickDecision("gave_up", planning_time=time.perf_counter() - t0)
    partial_lifts = spec.loop.partial_lifts and mode == "mog"
    alone = spec.loop.sog_alone and mode == "sog"
    decision = PickDecision("no_grasp")
    best = None  # (grasp, lifted ids) of the tested candidate that lifted the most objects
    pending = list(failures or ())  # remembered failures not yet met in this scene
    seen: list[FailedGroup] = []
    for group in groups:
        if partial_lifts and best is not None and len(best[1]) >= len(group):
            break
        res = around = None
        if failures is not None:
            around = around_group(scene, group, planner.gripper)
            res = _clear(recall(pending, group, around, avoid), scene, group, planner)
            decision.remembered += res is not None
        if res is None:
            res = planner.plan(scene, group, rng=rng, avoid=avoid, alone=alone)
        if failures is not None and not res.found:
            seen.append(FailedGroup(tuple(res.group), around, res))
        decision.plans.append(res)
        decision.groups_tried += 1
        decision.physics_checks += res.tested
        if res.found:
            decision.status, decision.grasp, decision.group = "grasp", res.grasp, res.group
            decision.expected = tuple(res.result.lifted) if res.result is not None else res.group
            # A grasp the lookahead's last resort found, replayed from its memory.
            decision.last_resort, decision.relaxed = bool(res.found_by), res.found_by == "relaxed"
            break
        if res.best_lift is not None and (best is None or len(res.best_lift[1]) > len(best[1])):
            best = res.best_lift
    if decision.status != "grasp" and partial_lifts and best is not None:
        decision.status, decision.grasp, decision.group = "grasp", best[0], tuple(best[1])
        decision.partial, decision.expected = True, tuple(best[1])
    kept: list[FailedGroup] = []  # the last resort's failures
    if decision.status != "grasp" and last_resort and planner.config.max_physics:
        memory = (pending, kept) if failures is not None else None
        _last_resort(scene, planner, decision, rng, avoid, partial_lifts, memory=memory)
    if failures is not None:
        decision.failures = tuple(seen + kept + pending)[:MEMORY_SIZE]
    decision.shapes = tuple(scene.objects[i].shape for i in decision.group)
    decision.planning_time = time.perf_counter() - t0
    return decision


def _push_mog(scene, planner, spec, rng, avoid, failures, *, grasp_unrecognised, pushes_left, exclude):
    """push-mog: Alg. 1's decision on its groups and the adjacent ones, then the pushes worth
    more than it (`consider_pushes`)."""
    d = next_pick(
        scene,
        planner,
        replace(spec, mode="mog"),
        rng,
        avoid,
        failures,
        grasp_unrecognised=grasp_unrecognised,
        adjacent=ADJACENT_GAP,
        exclude=exclude,
    )
    if (
        pushes_left > 0
        and spec.pushes.checks > 0
        and not d.unrecognised
        and d.status in ("grasp", "no_grasp")
    ):
        consider_pushes(scene, planner, spec, d, rng, avoid, memory=failures)
    d.lone = lone_reason(scene, planner, spec, d, pushes_left)
    return d


def _blobs(scene, planner, spec, rng, avoid, failures, *, grasp_unrecognised, t0) -> PickDecision:
    """No library object left: a clear table, or the unrecognised blobs planned as prisms.
    (Something the perception could not recognise is not a clear table.)"""
    blobs = unrecognised_scene(scene) if grasp_unrecognised else None
    if not blobs:
        status = "unrecognised" if scene.meta.get("unrecognised_blobs", 0) else "table_clear"
        return PickDecision(status, planning_time=time.perf_counter() - t0)
    d = next_pick(blobs, planner, spec, rng, avoid, failures)
    d.unrecognised = True
    if d.status != "grasp":
        d.status = "unrecognised"
    return d


def _mog_groups(scene, planner: GraspPlanner, spec: PlannerSpec, adjacent: float) -> list[tuple[int, ...]]:
    """Alg. 1's groups of ``scene`` (``spec.loop.grouping``), largest first; with ``adjacent``
    above 0 (push-mog), the groups of objects that meet within it too."""
    polys = scene.polygons()
    groups = ranked_groups(polys, planner.gripper, spec.loop.grouping, spec.loop.group_radius)
    if adjacent > 0:
        more = [g for g in adjacent_groups(polys, adjacent, planner.gripper.w_g) if g not in groups]
        groups = sorted(groups + more, key=lambda g: -len(g))
    return groups


def _clear(res, scene, group, planner: GraspPlanner):
    """A replayed plan (`recall`) whose grasp, or partial lift, puts the open jaws on what they
    must now keep off (`jaw_obstacles`: a grasp that took nothing since it was planned) loses
    it; a replayed grasp lost is None: plan the group."""
    if res is None or (blobs := jaw_obstacles(scene, group)) is None:
        return res
    if res.found and not jaw_collision_free(blobs, res.grasp, planner.gripper)[0]:
        return None
    if res.best_lift is not None and not jaw_collision_free(blobs, res.best_lift[0], planner.gripper)[0]:
        return replace(res, best_lift=None)
    return res


def _excluding(groups: list, exclude) -> list:
    excluded = {int(i) for i in exclude}
    return [g for g in groups if not excluded.intersection(g)]


def tally_misses(misses: tuple, targets: tuple, scene) -> tuple[tuple, list[int]]:
    """Failed grasps per object, across images whose object ids differ.

    ``misses``: ((shape, x, y, count), ...) as of the last image; ``targets``: ((shape, x, y),
    ...), the objects the grasp executed since meant to take; ``scene``: the new image. An
    object is found again as the nearest one of its shape within MISS_RADIUS of where it
    was. If every target is found again, the grasp took none of them (`missed`): each one's
    count goes up by one. Entries not found again are dropped (taken, or moved far).

    Returns the new misses (at the objects' new positions) and the ids, in ``scene``, of the
    objects grasped MAX_MISSES times in vain."""
    counts = {i: e[3] for e, i in zip(misses, _found_again(misses, scene), strict=True) if i is not None}
    hits = _found_again(targets, scene)
    if targets and None not in hits:  # as `missed`
        for i in hits:
            counts[i] = counts.get(i, 0) + 1
    new = tuple(
        (scene.objects[i].shape, float(scene.objects[i].x), float(scene.objects[i].y), n)
        for i, n in sorted(counts.items())
    )
    return new, sorted(i for i, n in counts.items() if n >= MAX_MISSES)


def tally_suspects(suspects: tuple, scene, footprints=(), targets: tuple = ()) -> tuple:
    """Objects a missed grasp's open jaws may have come down on, across images whose object
    ids differ (`LoopConfig.wary_neighbours`).

    ``suspects``: ((shape, x, y, margin), ...) as of the last image, each found again in
    ``scene`` as `tally_misses` finds its entries (dropped when not: taken, or moved far);
    ``footprints``: the jaws' rectangles of a grasp executed since that took none of
    ``targets`` (`planner.jaw_footprints`), or none. For each jaw, the non-target object whose
    outline comes nearest it, if within SUSPECT_NEAR, becomes a suspect with margin its gap
    plus SUSPECT_EXTRA (the larger if it was one already). Returns the new suspects, all of
    them found again, at the objects' positions in ``scene``."""
    margins = {i: e[3] for e, i in zip(suspects, _found_again(suspects, scene), strict=True) if i is not None}
    if len(footprints) and len(scene):
        hit = {i for i in _found_again(targets, scene) if i is not None}
        outlines = scene.shapely_polygons()
        for jaw in footprints:
            gaps = shapely.distance(shapely.Polygon(jaw), outlines)
            gaps[list(hit)] = np.inf
            i = int(np.argmin(gaps))
            if gaps[i] <= SUSPECT_NEAR:
                margins[i] = max(margins.get(i, 0.0), float(gaps[i]) + SUSPECT_EXTRA)
    return tuple(
        (scene.objects[i].shape, float(scene.objects[i].x), float(scene.objects[i].y), round(m, 4))
        for i, m in margins.items()
    )


def wary_outlines(suspects: tuple, scene) -> list[dict]:
    """``scene.meta["wary"]`` for `planner.jaw_obstacles`: each suspect's outline in ``scene``
    grown by its margin, with its shape and position (a group holding it is exempt)."""
    out = []
    for (_, _, _, m), i in zip(suspects, _found_again(suspects, scene), strict=True):
        if i is None:
            continue
        o = scene.objects[i]
        grown = shapely.Polygon(scene.polygon(i)).buffer(m, join_style="mitre")
        vertices = np.asarray(shapely.get_coordinates(shapely.normalize(grown).exterior))[:-1][::-1]  # CCW
        out.append({"shape": o.shape, "x": float(o.x), "y": float(o.y), "vertices": vertices.tolist()})
    return out


def missed(targets: tuple, scene) -> bool:
    """Whether the grasp meant to take ``targets`` ((shape, x, y), ...) took none of them:
    each is found again in ``scene`` (`tally_misses`)."""
    return bool(targets) and all(i is not None for i in _found_again(targets, scene))


def _found_again(entries, scene) -> list[int | None]:
    """Each (shape, x, y, ...) entry's object in ``scene``: the nearest of its shape within
    MISS_RADIUS, nearest pairs first, each object taken once; None where there is none."""
    objects = [(o.shape, float(o.x), float(o.y)) for o in scene.objects]
    pairs = sorted(
        (float(np.hypot(x - e[1], y - e[2])), k, i)
        for k, e in enumerate(entries)
        for i, (shape, x, y) in enumerate(objects)
        if shape == e[0] and np.hypot(x - e[1], y - e[2]) <= MISS_RADIUS
    )
    out: list[int | None] = [None] * len(entries)
    used = set()
    for _, k, i in pairs:
        if out[k] is None and i not in used:
            out[k] = i
            used.add(i)
    return out


def _last_resort(
    scene, planner: GraspPlanner, decision: PickDecision, rng, avoid, partial_lifts, *, memory=None
) -> None:
    """Plans each group the decision tried again with LAST_RESORT_CHECKS more physics checks,
    skipping the candidates already simulated (a remembered plan simulated none now); takes
    the first grasp found, or with ``partial_lifts`` the first partial lift. A robust check
    (`planning.robust`) is relaxed to its nominal one here; with ``relaxed_share``, first to
    its screen at that share (`RobustVerifier.relaxed`, each pass its own budget; the
    candidates its full screen refused are screened again).

    ``memory`` (pending, kept): with the failure memory on, a group a pass of an earlier
    decision (or the lookahead) planned with the whole of LAST_RESORT_CHECKS and found no
    grasp for is replayed from ``pending`` while everything within its reach lies where it
    did, and each pass's failures at that cap go to ``kept`` (`FailedGroup.stage`)."""
    tried = list(decision.plans)
    relaxed = getattr(planner.verifier, "relaxed", None)
    first_pass = relaxed() if relaxed is not None else None
    passes = [(first_pass, True)] if first_pass is not None else []
    passes.append((getattr(planner.verifier, "nominal", planner.verifier), False))
    for verifier, is_relaxed in passes:
        stage = "relaxed" if is_relaxed else "nominal"
        deeper = copy.copy(planner)
        deeper.verifier = verifier
        spent = 0
        for first in tried:
            if spent >= LAST_RESORT_TOTAL:
                break
            cap = min(LAST_RESORT_CHECKS, LAST_RESORT_TOTAL - spent)
            res = around = None
            if memory is not None:
                around = around_group(scene, first.group, planner.gripper)
                res = _clear(
                    recall(memory[0], first.group, around, avoid, stage), scene, first.group, planner
                )
                decision.remembered += res is not None
            if res is None:
                deeper.config = replace(planner.config, max_physics=cap, max_physics_large=None)
                # The nominal pass simulates again what the robust check refused for want of
                # robustness alone (its screen simulated nothing; a grasp that failed only
                # in a perturbed world lifts at the perceived poses), nothing else twice.
                skip = () if is_relaxed else [i for i in first.tested_indices if i not in first.not_robust]
                res = deeper.plan(scene, first.group, rng=rng, avoid=avoid, skip=skip)
                if res.found:
                    res = replace(res, found_by=stage)
                elif memory is not None and cap == LAST_RESORT_CHECKS:
                    memory[1].append(FailedGroup(tuple(res.group), around, res, stage))
            else:  # replayed: kept for the next decision too
                memory[1].append(FailedGroup(tuple(res.group), around, res, stage))
            decision.plans.append(res)
            decision.groups_tried += 1
            decision.physics_checks += res.tested
            spent += res.tested
            if res.found:
                decision.status, decision.grasp, decision.group = "grasp", res.grasp, res.group
                decision.expected = tuple(res.result.lifted)
            elif partial_lifts and res.best_lift is not None:  # a verified grasp of part of the group
                decision.status, decision.grasp, decision.group = (
                    "grasp",
                    res.best_lift[0],
                    tuple(res.best_lift[1]),
                )
                decision.partial, decision.expected = True, tuple(res.best_lift[1])
            else:
                continue
            decision.last_resort, decision.relaxed = True, is_relaxed
            return


def unrecognised_scene(scene) -> Scene:
    """The unrecognised blobs of a perceived ``scene`` (``meta["unrecognised"]``) as objects:
    each a prism of its outline, as tall as its top, of the library's usual density. A blob's
    shape is named after its outline, so the verifier never mistakes one blob for another."""
    shapes, objects = {}, []
    for blob in scene.meta.get("unrecognised", ()):
        v = np.asarray(blob["vertices"], dtype=float)
        if len(v) < 3 or abs(polygon_area(v)) < 1e-8:  # an outline with no area
            continue
        top = max(float(blob["top"]), 0.005)
        digest = hashlib.sha1(np.round(np.append(v.ravel(), top), 5).tobytes()).hexdigest()[:10]
        name = f"unrecognised_{digest}"
        c = polygon_centroid(v)
        try:
            shapes[name] = make_shape(
                name,
                {"vertices": (v - c).tolist(), "height": top, "density": 1000.0, "color": [0.5, 0.5, 0.5]},
            )
        except MogError:  # not a convex outline
            continue
        objects.append(SceneObject(name, float(c[0]), float(c[1]), 0.0))
    library = replace(scene.library, shapes={**scene.library.shapes, **shapes})
    return Scene(objects, library, table=scene.table)
