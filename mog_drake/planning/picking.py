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

import copy
import hashlib
import time
from dataclasses import dataclass, field, replace

import numpy as np

from mog_drake.errors import MogError
from mog_drake.geometry import objects_in_reach, ranked_groups
from mog_drake.geometry.groups import adjacent_groups
from mog_drake.geometry.polygon import polygon_area, polygon_centroid
from mog_drake.geometry.push import PUSH_GAP, Push, push_candidates, push_duration
from mog_drake.planning.board import Board, BoardReader
from mog_drake.planning.config import PlannerSpec
from mog_drake.planning.planner import GraspPlanner, PlanResult, repeats
from mog_drake.planning.protocol import GraspResult
from mog_drake.scenes import Scene, SceneObject, make_shape

# A remembered failure applies while every object within reach of its group is where it was
# (each vertex within this distance: perception's error on a resting object is about 1 mm).
MEMORY_TOL = 0.003  # m
MEMORY_REACH_MARGIN = 0.03  # m around the gripper's reach (the physics check uses 0.02)
MEMORY_SIZE = 64
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
# push-mog: objects whose outlines come this close form a group too (a push leaves PUSH_GAP
# between them, and the pushed object may turn a little as it stops).
ADJACENT_GAP = PUSH_GAP + 0.004  # m
# push-mog: physics checks for the grasp a simulated push sets up (its first candidates lift
# it if any does: the push made the group compact).
PUSH_GRASP_CHECKS = 2


@dataclass(frozen=True, eq=False)  # compared by identity (it holds arrays)
class FailedGroup:
    """A group the planner found no grasp for, with what the physics check saw, or (``result``
    found: the lookahead's, see `lookahead`) the grasp it found. ``around`` holds (id, shape,
    vertices) of every object within reach of the group then: the check's verdict depends on
    nothing else, so while they are all where they were it stands."""

    group: tuple[int, ...]
    around: tuple
    result: PlanResult


@dataclass(frozen=True, eq=False)
class FailedPush:
    """push-mog: a push that was simulated and did not pay: it failed (``lifted`` 0) or the
    grasp it set up lifted ``lifted`` objects, too few to beat the grasp then. ``around``
    holds (id, shape, vertices) of every object within reach of its group (the pushed object
    and those it joins): while they are all where they were, simulating it again would give
    the same verdict, so it is not simulated again unless the grasp it would compete with
    now lifts fewer."""

    target: int
    toward: int
    group: tuple[int, ...]
    around: tuple
    lifted: int


@dataclass(frozen=True, eq=False)
class PaidPush:
    """push-mog: a push the lookahead simulated that paid (see `lookahead`): ``push``, the
    ``group`` it sets up, and the grasp of that group planned where the simulated push left it,
    which lifted ``lifted``. ``around`` as `FailedPush`'s, before the push; ``after`` holds
    (id, SceneObject) of each of those objects where the push left them (it moved nothing
    else). While they are all where they were before it, the push and its grasp are replayed
    with no physics."""

    push: Push
    group: tuple[int, ...]
    around: tuple
    lifted: tuple[int, ...]
    grasp: np.ndarray
    after: tuple


def _around(scene, group, gripper) -> tuple:
    ids = objects_in_reach(scene, group, gripper, MEMORY_REACH_MARGIN)
    return tuple((i, scene.objects[i].shape, scene.polygon(i)) for i in ids)


def _match(old: tuple, new: tuple, tol: float = MEMORY_TOL) -> dict[int, int] | None:
    """Old id -> new id if every object of ``old`` is one of ``new`` (same shape, every vertex
    within ``tol`` of one of the other's: a symmetric shape turned by its symmetry matches)
    and no object is new; else None."""
    if len(old) != len(new):
        return None
    ids, free = {}, list(new)
    for i, shape, v in old:
        for k, (j, shape_j, w) in enumerate(free):
            if shape_j == shape and len(w) == len(v):
                d = np.linalg.norm(v[:, None, :] - w[None, :, :], axis=2)
                if d.min(axis=1).max() <= tol:
                    ids[i] = j
                    del free[k]
                    break
        else:
            return None
    return ids


def _same_group(f_group, f_around, group, around) -> dict[int, int] | None:
    """Old id -> new id if ``f_group`` with ``f_around`` around it (as `_around` gives) is
    ``group`` now, every object around it where it was (``around``, now); else None."""
    if len(f_group) != len(group) or (ids := _match(f_around, around)) is None:
        return None
    return ids if {ids.get(i, -1) for i in f_group} == set(group) else None


def _unknown(entries, *known) -> list:
    """``entries`` less those (the same objects) in any of ``known``: the lookahead's memory
    holds the entries it was given, which the decision has already."""
    have = {id(f) for k in known for f in k}
    return [f for f in entries if id(f) not in have]


def _recall(pending: list, group, around, avoid) -> tuple[bool, PlanResult | None]:
    """The first remembered verdict in ``pending`` of ``group`` with ``around`` (taken out of
    ``pending``): (True, its replay), or (True, None) when its grasp repeats one to avoid;
    (False, None) if none is remembered."""
    for k, f in enumerate(pending):
        if isinstance(f, FailedGroup) and (ids := _same_group(f.group, f.around, group, around)) is not None:
            del pending[k]
            return True, _replay(f, ids, group, avoid)
    return False, None


def _replay(f: FailedGroup, ids: dict[int, int], group: tuple[int, ...], avoid=()) -> PlanResult | None:
    """The remembered plan, in the new scene's object ids, with no physics run now. Its partial
    lift is dropped if it repeats a grasp to avoid (the robot just tried it). A remembered
    grasp that was found (the lookahead's, see `lookahead`) is None if it repeats one: plan
    the group again."""
    if f.result.found:
        if repeats([f.result.grasp], avoid)[0]:
            return None
        lifted = f.result.result.lifted if f.result.result is not None else f.group
        return replace(
            f.result,
            group=tuple(group),
            tested=0,
            tested_indices=[],
            best_lift=None,
            result=GraspResult(True, lifted=[ids[i] for i in lifted if i in ids]),
        )
    lift = f.result.best_lift
    if lift is not None and repeats([lift[0]], avoid)[0]:
        lift = None
    return replace(
        f.result,
        group=tuple(group),
        tested=0,
        tested_indices=[],
        best_lift=None if lift is None else (lift[0], [ids[i] for i in lift[1] if i in ids]),
        result=None,
    )


@dataclass
class PickDecision:
    """status: "grasp" (grasp and group set), "push" (push set: push-mog), "table_clear",
    "no_grasp", "unrecognised" (no library object is left but perception sees something
    it cannot recognise), or "gave_up" (every object left was grasped MAX_MISSES times in
    vain: see `tally_misses`)."""

    status: str
    grasp: np.ndarray | None = None
    group: tuple[int, ...] = ()
    # The grasp is of unrecognised blobs, planned as prisms of their outline (group and
    # expected then index the blobs, not the scene's objects).
    unrecognised: bool = False
    last_resort: bool = False  # found by the last resort (see next_pick)
    groups_tried: int = 0
    partial: bool = False  # the grasp lifted part of a larger group it was planned for
    expected: tuple[int, ...] = ()  # objects the physics check lifted with this grasp
    shapes: tuple[str, ...] = ()  # the shape of each object of ``group``, as perceived
    physics_checks: int = 0
    planning_time: float = 0.0
    plans: list[PlanResult] = field(default_factory=list)
    remembered: int = 0  # groups not planned again: their failure was remembered
    # push-mog: pushes not simulated now: they did not pay before, or the lookahead found them to pay
    remembered_pushes: int = 0
    # The lookahead's verdicts came in while this decision was planned (``late``); the
    # simulated time it waited for them beyond its own clock (s).
    merged: bool = False
    waited: float = 0.0
    from_board: int = 0  # verdicts taken from the lookahead's board
    # The entry of the grasp found, as posted on a board (``post``; see `lookahead`).
    found_entry: FailedGroup | None = None
    # What to remember for the next decision: failures seen (or replayed) now, then the older
    # ones not met this time (see next_pick's ``failures``).
    failures: tuple[FailedGroup | FailedPush | PaidPush, ...] = ()
    # push-mog: the push to make (`mog_drake.geometry.push.Push`); ``group`` is then the group
    # it sets up, ``expected`` what the physics check lifted with that group's grasp after the
    # push, and ``grasp`` that grasp if it is to follow at once (planner.push_then_grasp);
    # ``now``: the objects the grasp that was possible without the push lifted.
    push: Push | None = None
    now: int = 0
    after: Scene | None = None  # the table the simulated push left (the lookahead plans on it)

    def to_dict(self) -> dict:
        return {
            "status": self.status,
            **({"push": self.push.to_dict(), "now": self.now} if self.push is not None else {}),
            "grasp": None if self.grasp is None else [float(v) for v in self.grasp],
            "group": list(self.group),
            "unrecognised": self.unrecognised,
            "last_resort": self.last_resort,
            "groups_tried": self.groups_tried,
            "partial": self.partial,
            "expected": list(self.expected),
            "shapes": list(self.shapes),
            "physics_checks": self.physics_checks,
            "planning_time": self.planning_time,
            "remembered": self.remembered,
            "remembered_pushes": self.remembered_pushes,
            "merged": self.merged,
            "waited": self.waited,
            "from_board": self.from_board,
        }


def next_pick(
    scene,
    planner: GraspPlanner,
    spec: PlannerSpec | None = None,
    rng: np.random.Generator | None = None,
    avoid=(),
    failures: tuple[FailedGroup | FailedPush | PaidPush, ...] | None = None,
    grasp_unrecognised: bool = True,
    pushes_left: int = 0,
    adjacent: float = 0.0,
    exclude=(),
    late: BoardReader | None = None,
    post: Board | None = None,
) -> PickDecision:
    """The next grasp for the objects of ``scene``.

    ``spec`` (`PlannerSpec`, its defaults when None) says how; the grasp planner is given.

    mode "mog": Alg. 1, the largest groups first. ``grouping`` "radius" forms the groups as the
    paper does (`create_obj_groups` with ``group_radius``); "conditions" (an extension) forms
    them from the grasps that satisfy the necessary conditions (`condition_groups`).
    mode "sog": the paper's single-object baseline, the same planner restricted to one object
    chosen at random (objects are tried in a random order until one has a grasp).

    partial_lifts (mog only; an extension of Alg. 1): a candidate that the physics check saw
    lift only k objects of a larger group is still a verified grasp of those k. Once every
    group left to try has at most k objects, that grasp is taken instead of planning them, and
    it is taken rather than giving up when no group succeeds.

    avoid: grasps not to try again (the robot's last few), so that a grasp the physics check
    trusts but the world keeps failing is not repeated attempt after attempt.

    failures (an extension; None: off): the previous decision's ``failures``. A group found
    to have no grasp is not planned again while every object within its reach lies where it
    did (its physics checks would replay the same verdicts); its remembered plan, partial lift
    included, stands in. Picking one group leaves most of the table untouched, so without
    this the same failing groups are simulated again before every attempt.

    last_resort (an extension): when no group has a grasp within the planner's cap on physics
    checks per group, each is planned again, in the same order, with up to LAST_RESORT_CHECKS
    more checks (LAST_RESORT_TOTAL in all) before the decision gives up (a run ends on
    "no_grasp").

    grasp_unrecognised (an extension): once no library object is left, the blobs perception
    could not recognise (a prism knocked onto its side) are planned as prisms of their outline
    and top height (``unrecognised_scene``); without a grasp for them the status is
    "unrecognised".

    mode "push-mog" (an extension): Alg. 1's grasp, or a consolidating push when that is
    worth more (see `_consider_pushes`; at most ``pushes_left`` more). Its grasps are
    planned for Alg. 1's groups and for the groups of objects that meet within
    ``ADJACENT_GAP`` (``adjacent``, `adjacent_groups`): a push leaves two bars end to end,
    farther apart than the group radius.

    exclude: objects given up on (`tally_misses`): no group holding one is planned; when they
    are all that is left, the status is "gave_up".

    late (with ``failures``; an extension): the board of a lookahead that was not done when
    the image came (`mog_drake.planning.board`). Before each group, the verdicts it has posted
    by then (in simulated time) join ``failures``' for the groups still to plan; a group it
    is planning then is not planned here: the decision waits for its verdict.

    post (with ``failures``; an extension): the board this plan writes on (the lookahead's):
    each group it simulates (its claim), then each verdict.

    decision_budget_s (mog, with partial_lifts; an extension): once this thread has spent
    that much time on the decision, on ``planner.clock`` (its CPU time, or the wall
    clock's), and holds a verified partial lift, no more groups are planned and no more
    candidates simulated: the partial lift is taken."""
    spec = spec or PlannerSpec()
    spec.check()
    if spec.mode == "push-mog":
        d = next_pick(
            scene,
            planner,
            replace(spec, mode="mog"),
            rng,
            avoid,
            failures,
            grasp_unrecognised,
            adjacent=ADJACENT_GAP,
            exclude=exclude,
            late=late,
            post=post,
        )
        if (
            pushes_left > 0
            and spec.push_checks > 0
            and not d.unrecognised
            and d.status in ("grasp", "no_grasp")
        ):
            memory = failures
            if failures is not None and late is not None:
                d.merged |= bool(late.new())
                memory = tuple(failures) + tuple(_unknown(late.got, failures))
            _consider_pushes(scene, planner, spec, d, rng, avoid, memory)
        return d
    mode, last_resort = spec.mode, spec.last_resort
    t0 = time.perf_counter()
    deadline = planner.clock() + spec.decision_budget_s if spec.decision_budget_s > 0 else None
    if len(scene) == 0:
        # Something the perception could not recognise is not a clear table.
        blobs = unrecognised_scene(scene) if grasp_unrecognised else None
        if not blobs:
            status = "unrecognised" if scene.meta.get("unrecognised_blobs", 0) else "table_clear"
            return PickDecision(status, planning_time=time.perf_counter() - t0)
        d = next_pick(blobs, planner, spec, rng, avoid, failures)
        d.unrecognised = True
        if d.status != "grasp":
            d.status = "unrecognised"
        return d
    if mode == "mog":
        groups = _mog_groups(scene, planner, spec, adjacent)
    else:
        if rng is None:
            raise MogError("single-object picking draws objects at random: pass a seeded numpy Generator")
        groups = [(int(i),) for i in rng.permutation(len(scene))]
    if len(exclude):
        groups = _excluding(groups, exclude)
        if not groups:
            return PickDecision("gave_up", planning_time=time.perf_counter() - t0)
    partial_lifts = spec.partial_lifts and mode == "mog"
    if not partial_lifts:
        deadline = None  # the budget ends a search only with a verified partial lift in hand
    decision = PickDecision("no_grasp")
    best = None  # (grasp, lifted ids) of the tested candidate that lifted the most objects
    pending = list(failures or ())  # remembered failures not yet met in this scene
    seen: list[FailedGroup] = []
    for group in groups:
        if partial_lifts and best is not None and len(best[1]) >= len(group):
            break
        if best is not None and deadline is not None and planner.clock() > deadline:
            break  # past the budget: the verified partial lift in hand
        res = None
        if failures is not None:
            around = _around(scene, group, planner.gripper)
            while True:
                if late is not None and (got := late.new()):
                    pending += _unknown(got, failures, pending)
                    decision.merged = True
                met, res = _recall(pending, group, around, avoid)
                # The lookahead is planning this group: wait for its verdict, not plan it twice.
                if (
                    met
                    or late is None
                    or (c := late.claimed()) is None
                    or _same_group(*c, group, around) is None
                ):
                    break
                late.wait()
            if res is not None:
                decision.remembered += 1
        if res is None:
            if post is not None and failures is not None:
                post.claim(group, around)
            res = planner.plan(
                scene, group, rng=rng, avoid=avoid, deadline=deadline, fallback=best is not None
            )
        if failures is not None and not res.found and not res.cut_short:
            seen.append(FailedGroup(tuple(res.group), around, res))
            if post is not None:
                post.post(seen[-1])
        decision.plans.append(res)
        decision.groups_tried += 1
        decision.physics_checks += res.tested
        if res.found:
            if post is not None and failures is not None:
                decision.found_entry = FailedGroup(tuple(res.group), around, res)
                post.post(decision.found_entry)
            decision.status, decision.grasp, decision.group = "grasp", res.grasp, res.group
            decision.expected = tuple(res.result.lifted) if res.result is not None else res.group
            break
        if res.best_lift is not None and (best is None or len(res.best_lift[1]) > len(best[1])):
            best = res.best_lift
    if decision.status != "grasp" and partial_lifts and best is not None:
        decision.status, decision.grasp, decision.group = "grasp", best[0], tuple(best[1])
        decision.partial, decision.expected = True, tuple(best[1])
    if decision.status != "grasp" and last_resort and planner.config.max_physics:
        _last_resort(scene, planner, decision, rng, avoid, partial_lifts)
    if failures is not None:
        decision.failures = tuple(seen + pending)[:MEMORY_SIZE]
    if late is not None:
        decision.waited, decision.from_board = late.waited, len(late.got)
    decision.shapes = tuple(scene.objects[i].shape for i in decision.group)
    decision.planning_time = time.perf_counter() - t0
    return decision


def _mog_groups(scene, planner: GraspPlanner, spec: PlannerSpec, adjacent: float) -> list[tuple[int, ...]]:
    """Alg. 1's groups of ``scene`` (``spec.grouping``), largest first; with ``adjacent``
    above 0 (push-mog), the groups of objects that meet within it too."""
    polys = scene.polygons()
    groups = ranked_groups(polys, planner.gripper, spec.grouping, spec.group_radius)
    if adjacent > 0:
        more = [g for g in adjacent_groups(polys, adjacent, planner.gripper.w_g) if g not in groups]
        groups = sorted(groups + more, key=lambda g: -len(g))
    return groups


def _excluding(groups: list, exclude) -> list:
    excluded = {int(i) for i in exclude}
    return [g for g in groups if not excluded.intersection(g)]


def tally_misses(misses: tuple, targets: tuple, scene) -> tuple[tuple, list[int]]:
    """Failed grasps per object, across images whose object ids differ.

    ``misses``: ((shape, x, y, count), ...) as of the last image; ``targets``: ((shape, x, y),
    ...), the objects the grasp executed since meant to take; ``scene``: the new image. An
    object is found again as the nearest one of its shape within MISS_RADIUS of where it
    was. If every target is found again, the grasp took none of them: each one's count goes
    up by one. Entries not found again are dropped (taken, or moved far).

    Returns the new misses (at the objects' new positions) and the ids, in ``scene``, of the
    objects grasped MAX_MISSES times in vain."""
    objects = [(o.shape, float(o.x), float(o.y)) for o in scene.objects]

    def found(entries) -> list[int | None]:
        """Each (shape, x, y, ...) entry's object in ``scene``, or None; nearest first, an
        object taken once."""
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

    counts = {i: e[3] for e, i in zip(misses, found(misses), strict=True) if i is not None}
    hits = found(targets)
    if targets and all(i is not None for i in hits):
        for i in hits:
            counts[i] = counts.get(i, 0) + 1
    new = tuple(
        (scene.objects[i].shape, float(scene.objects[i].x), float(scene.objects[i].y), n)
        for i, n in sorted(counts.items())
    )
    return new, sorted(i for i, n in counts.items() if n >= MAX_MISSES)


def lookahead(
    scene,
    decision: PickDecision,
    planner: GraspPlanner,
    spec: PlannerSpec,
    rng=None,
    avoid=(),
    grasp_unrecognised: bool = True,
    pushes_left: int = 0,
    board: Board | None = None,
) -> tuple[FailedGroup | FailedPush | PaidPush, ...]:
    """What the next decision can reuse, planned before its image (an extension; see
    `PlannerSpec.lookahead`): the memory of `next_pick` (``failures``) planned on ``scene``
    without the objects ``decision`` grasps, as if they were gone and nothing else had moved,
    plus the grasp it found there. In the next image, each group whose surroundings are
    where they were is replayed from it with no physics (its failure, or its grasp); the
    groups the grasp disturbed are planned again.

    push-mog, with ``pushes_left`` above 0: the pushes are considered too, as the decision
    would. The pushes that did not pay join the memory (`FailedPush`), and a push that paid
    with its grasp (`PaidPush`), which the next decision replays with no physics if its
    objects are where they were: a push decision simulates pushes and their grasps (6-10 s of
    CPU), which the lookahead does while the arm moves.

    board: where the next decision, if its image comes first, reads this plan as it goes (see
    `mog_drake.planning.board`): each group as it is simulated, each verdict, and at the end
    the rest of the memory. It is finished however this returns."""
    if board is not None:
        board.start()
    try:
        memory = _lookahead(
            scene, decision, planner, spec, rng, avoid, grasp_unrecognised, pushes_left, board
        )
        if board is not None:
            for entry in memory:
                board.post(entry)  # those posted already are not posted twice
        return memory
    finally:
        if board is not None:
            board.finish()


def without_grasped(scene, decision: PickDecision) -> Scene:
    """``scene`` without the objects ``decision``'s grasp takes (its group and what the
    physics check lifted), as the lookahead plans it."""
    gone = set(decision.group) | set(decision.expected)
    return replace(scene, objects=[o for i, o in enumerate(scene.objects) if i not in gone], group=None)


def _lookahead(scene, decision, planner, spec, rng, avoid, grasp_unrecognised, pushes_left, board):
    rest = without_grasped(scene, decision)
    if len(rest) == 0:
        return ()
    ahead = next_pick(
        rest,
        planner,
        spec,
        rng,
        avoid,
        decision.failures,
        grasp_unrecognised,
        pushes_left=pushes_left,
        post=board,
    )
    memory = list(ahead.failures)
    found = ahead.plans[-1] if ahead.plans else None  # Alg. 1's grasp (a push's too)
    if (
        ahead.status in ("grasp", "push")
        and not (ahead.partial or ahead.unrecognised)
        and found is not None
        and found.found
    ):
        entry = ahead.found_entry
        if entry is None or entry.result is not found:
            entry = FailedGroup(tuple(found.group), _around(rest, found.group, planner.gripper), found)
        memory.insert(0, entry)
    if ahead.status == "push" and (paid := _paid_push(rest, ahead, planner.gripper)) is not None:
        memory.insert(0, paid)
    return tuple(memory[:MEMORY_SIZE])


def _paid_push(before, d: PickDecision, gripper) -> PaidPush | None:
    """Push decision ``d`` on ``before`` as a `PaidPush`; None if its grasp does not follow at
    once (nothing to replay) or the simulated push moved an object beyond its group's reach
    (its replay would miss that)."""
    if d.grasp is None or d.after is None or len(d.after.objects) != len(before.objects):
        return None
    around = _around(before, d.group, gripper)
    inside = {i for i, _, _ in around}
    for i in range(len(before.objects)):
        if i not in inside:
            if np.abs(before.polygon(i) - d.after.polygon(i)).max() > MEMORY_TOL:
                return None
    after = tuple((i, d.after.objects[i]) for i in sorted(inside))
    return PaidPush(d.push, tuple(d.group), around, tuple(d.expected), np.asarray(d.grasp), after)


def _same_push(target: int, toward: int, f_group, f_around, p: Push, group, around) -> dict[int, int] | None:
    """Old id -> new id if a remembered push (of ``target`` to ``toward``, setting up
    ``f_group``, with ``f_around`` around it) is push ``p`` of ``group`` now, every object
    around it where it was (``around``, now); else None."""
    ids = _same_group(f_group, f_around, group, around)
    if ids is None or ids.get(target) != p.target or ids.get(toward) != p.toward:
        return None
    return ids


def _replay_push(known, p: Push, group, around, scene, avoid):
    """The remembered `PaidPush` of push ``p`` of ``group`` (same objects, each where it
    was) in ``scene``'s ids: (its entry, the push, what its grasp lifted, the grasp, the table
    it leaves); None if there is none, or its grasp repeats one to avoid."""
    for f in known:
        ids = _same_push(f.push.target, f.push.toward, f.group, f.around, p, group, around)
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


def _consider_pushes(
    scene, planner: GraspPlanner, spec: PlannerSpec, d: PickDecision, rng, avoid, memory=None
) -> None:
    """push-mog: turns decision ``d`` (Alg. 1's) into a push when its grasp lifts fewer than
    ``push_below`` objects and the push and the grasp it sets up are expected to take more
    objects per second of robot time than ``d``'s grasp:
    m / (push_time_s + T + grasp_time_s) > n / grasp_time_s, n being what ``d``'s grasp
    lifted in the physics check, m what the grasp after the push lifted, and T the push's
    own time along its line (`push_duration`).

    Candidates (`push_candidates`): an object pushed along the line of centres to another one,
    joining the largest group (of Alg. 1's, on this table) that holds the other one and not
    it, and fits the jaws. Those whose group is large enough to beat ``d`` by that rule, even
    if the grasp lifts it all, are simulated largest group first, then shortest push, up to
    ``push_checks`` of them: the push in physics (the verifier's ``push``), then the group's
    grasp planned on the table the push leaves (the same planner, physics included).

    ``memory`` (the previous decision's, with remember_failures; None: off): a push that did
    not pay before (`FailedPush`), whose surroundings are where they were, is not simulated
    again and does not count against ``push_checks``: the next candidate is simulated
    instead. Pushes that do not pay now are added to ``d.failures``. A push the lookahead
    found to pay (`PaidPush`), whose objects are where they were, is taken with its grasp and
    nothing is simulated."""
    t0 = time.perf_counter()
    verifier = planner.verifier
    if not hasattr(verifier, "push"):
        raise MogError("push-mog needs a verifier that simulates pushes (DrakeVerifier)")
    n_now = len(d.expected) if d.status == "grasp" else 0
    if n_now >= spec.push_below:
        return
    tp, tg = spec.push_time_s, spec.grasp_time_s
    polys = scene.polygons()
    groups = ranked_groups(polys, planner.gripper, spec.grouping, spec.group_radius)
    w_g = planner.gripper.w_g
    options = []
    for p in push_candidates(polys, range(len(scene)), planner.gripper, spec.push_reach, planner.keep_out):
        joined = next((g for g in groups if p.toward in g and p.target not in g), (p.toward,))
        group = tuple(sorted((p.target, *joined)))
        if polys.d_fmin[list(group)].sum() > w_g:
            continue
        if len(group) / (tp + push_duration(p, spec.push_speed) + tg) > n_now / tg:
            options.append((-len(group), p.distance, p, group))
    options.sort(key=lambda o: o[:2])
    best, checks, simulated, failed = None, 0, 0, []
    known = [f for f in memory or () if isinstance(f, FailedPush)]
    paid = [f for f in memory or () if isinstance(f, PaidPush)]
    for _, _, p, group in options if paid else ():  # the lookahead's push, if it stands
        hit = _replay_push(paid, p, group, _around(scene, group, planner.gripper), scene, avoid)
        if hit is not None and len(hit[2]) / (tp + push_duration(hit[1], spec.push_speed) + tg) > n_now / tg:
            used, push, lifted, grasp, after = hit
            best = (push, lifted, group, grasp, after)
            d.remembered_pushes += 1
            d.failures = tuple(f for f in d.failures if f is not used)
            options = []  # nothing to simulate
            break
    quick = copy.copy(planner)  # the grasps a push sets up: PUSH_GRASP_CHECKS checks each
    quick.config = replace(planner.config, max_physics=PUSH_GRASP_CHECKS)
    for _, _, p, group in options:
        if simulated >= spec.push_checks:
            break
        around = _around(scene, group, planner.gripper) if memory is not None else ()
        if memory is not None and _did_not_pay(
            known, p, group, around, n_now / tg, tp + push_duration(p, spec.push_speed) + tg
        ):
            d.remembered_pushes += 1
            continue
        simulated += 1
        r = verifier.push(scene, p, spec.push_speed)
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
        rate = len(lifted) / (tp + push_duration(p, spec.push_speed) + tg)
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
        d.grasp = best[3] if spec.push_then_grasp else None
        d.after = best[4]
        d.shapes = tuple(scene.objects[i].shape for i in d.group)
        d.partial = d.last_resort = False
    d.planning_time += time.perf_counter() - t0


def _did_not_pay(known, p, group, around, now_rate: float, push_time: float) -> bool:
    """Whether push ``p`` of ``group`` is a remembered `FailedPush` (same objects, each where
    it was) that would not pay now either: it failed, or what its grasp lifted over
    ``push_time`` does not beat ``now_rate`` (objects per second of the grasp now)."""
    for f in known:
        if _same_push(f.target, f.toward, f.group, f.around, p, group, around) is not None:
            return f.lifted == 0 or f.lifted / push_time <= now_rate
    return False


def _last_resort(scene, planner: GraspPlanner, decision: PickDecision, rng, avoid, partial_lifts) -> None:
    """Plans each group the decision tried again with LAST_RESORT_CHECKS more physics checks,
    skipping the candidates already simulated (a remembered plan simulated none now); takes
    the first grasp found, or with ``partial_lifts`` the first partial lift."""
    deeper = copy.copy(planner)
    spent = 0
    for first in list(decision.plans):
        if spent >= LAST_RESORT_TOTAL:
            return
        deeper.config = replace(
            planner.config, max_physics=min(LAST_RESORT_CHECKS, LAST_RESORT_TOTAL - spent)
        )
        res = deeper.plan(scene, first.group, rng=rng, avoid=avoid, skip=first.tested_indices)
        decision.plans.append(res)
        decision.groups_tried += 1
        decision.physics_checks += res.tested
        spent += res.tested
        if res.found:
            decision.status, decision.grasp, decision.group = "grasp", res.grasp, res.group
            decision.expected = tuple(res.result.lifted)
            decision.last_resort = True
            return
        if partial_lifts and res.best_lift is not None:  # a verified grasp of part of the group
            decision.status, decision.grasp, decision.group = (
                "grasp",
                res.best_lift[0],
                tuple(res.best_lift[1]),
            )
            decision.partial, decision.expected, decision.last_resort = True, tuple(res.best_lift[1]), True
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
