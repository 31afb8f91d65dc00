"""What a picking decision remembers and returns: the groups whose grasps failed in physics,
the pushes that did not pay and the one that did (each matched to a later table by where the
objects around it lie), and the decision itself (`PickDecision`)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from mog_drake.geometry import objects_in_reach
from mog_drake.geometry.push import Push
from mog_drake.planning.planner import PlanResult, repeats
from mog_drake.planning.protocol import GraspResult
from mog_drake.scenes import Scene

# A remembered failure applies while every object within reach of its group is where it was
# (each vertex within this distance: perception's error on a resting object is about 1 mm).
MEMORY_TOL = 0.003  # m
MEMORY_REACH_MARGIN = 0.03  # m around the gripper's reach (the physics check uses 0.02)
MEMORY_SIZE = 64


@dataclass(frozen=True, eq=False)  # compared by identity (it holds arrays)
class FailedGroup:
    """A group the planner found no grasp for, with what the physics check saw, or (``result``
    found: the lookahead's, see `lookahead`) the grasp it found. ``around`` holds (id, shape,
    vertices) of every object within reach of the group then: the check's verdict depends on
    nothing else, so while they are all where they were it stands. ``stage``: the pass that
    planned it, "" for the decision's own, or a pass of the last resort ("relaxed",
    "nominal": `mog_drake.planning.picking._last_resort`), whose failures are replayed by
    that pass only."""

    group: tuple[int, ...]
    around: tuple
    result: PlanResult
    stage: str = ""


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


def around_group(scene, group, gripper) -> tuple:
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


def drawn_first(groups: list, memory, scene) -> list:
    """sog's ``groups`` (single objects in a random order) with the object whose grasp the
    lookahead found (`lookahead`: the first found grasp in ``memory``) first, if it lies where
    it was then (every vertex within MEMORY_TOL); else ``groups`` as they are. Its grasp is
    replayed (`recall`) only if nothing within its reach moved either."""
    found = next((f for f in memory if isinstance(f, FailedGroup) and f.result.found), None)
    if found is None or len(found.group) != 1:
        return groups
    # `around_group` holds the group's own objects: the drawn one, where it was then
    old = next(a for a in found.around if a[0] == found.group[0])
    for j, o in enumerate(scene.objects):
        if o.shape == old[1] and _match((old,), ((j, o.shape, scene.polygon(j)),)) is not None:
            return [(j,)] + [g for g in groups if g != (j,)]
    return groups


def same_group(f_group, f_around, group, around) -> dict[int, int] | None:
    """Old id -> new id if ``f_group`` with ``f_around`` around it (as `around_group` gives) is
    ``group`` now, every object around it where it was (``around``, now); else None."""
    if len(f_group) != len(group) or (ids := _match(f_around, around)) is None:
        return None
    return ids if {ids.get(i, -1) for i in f_group} == set(group) else None


def recall(pending: list, group, around, avoid, stage: str = "") -> PlanResult | None:
    """The replay of the first remembered verdict in ``pending`` of ``group`` with ``around``
    planned by pass ``stage`` (taken out of ``pending``); None if none is remembered, or its
    grasp repeats one to avoid: plan the group."""
    for k, f in enumerate(pending):
        if (
            isinstance(f, FailedGroup)
            and f.stage == stage
            and (ids := same_group(f.group, f.around, group, around)) is not None
        ):
            del pending[k]
            return _replay(f, ids, group, avoid)
    return None


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
    relaxed: bool = False  # by its relaxed screen (planner.robust.relaxed_share)
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
    # What to remember for the next decision: failures seen (or replayed) now, then the older
    # ones not met this time (see next_pick's ``failures``).
    failures: tuple[FailedGroup | FailedPush | PaidPush, ...] = ()
    # push-mog: the push to make (`mog_drake.geometry.push.Push`); ``group`` is then the group
    # it sets up, ``expected`` what the physics check lifted with that group's grasp after the
    # push, and ``grasp`` that grasp if it is to follow at once (planner.pushes.then_grasp);
    # ``now``: the objects the grasp that was possible without the push lifted.
    push: Push | None = None
    now: int = 0
    # push-mog, a grasp of one object: why no push set up more (`pushing.lone_reason`).
    lone: str = ""
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
            **({"lone": self.lone} if self.lone else {}),
        }
