"""Planning ahead (an extension of Alg. 1): while the arm carries a grasp to the bin, the next
decision is planned on the table as it will be without the grasped objects; the real
decision replays its verdicts."""

from __future__ import annotations

from dataclasses import replace

from mog_drake.planning.config import PlannerSpec
from mog_drake.planning.decision import (
    MEMORY_SIZE,
    FailedGroup,
    FailedPush,
    PaidPush,
    PickDecision,
    around_group,
)
from mog_drake.planning.picking import next_pick
from mog_drake.planning.planner import GraspPlanner
from mog_drake.planning.pushing import paid_push
from mog_drake.scenes import Scene


def lookahead(
    scene,
    decision: PickDecision,
    planner: GraspPlanner,
    spec: PlannerSpec,
    rng=None,
    avoid=(),
    *,
    grasp_unrecognised: bool = True,
    pushes_left: int = 0,
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
    objects are where they were: a push decision simulates pushes and their grasps, which
    the lookahead does while the arm moves."""
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
        grasp_unrecognised=grasp_unrecognised,
        pushes_left=pushes_left,
    )
    memory = list(ahead.failures)
    found = ahead.plans[-1] if ahead.plans else None  # Alg. 1's grasp (a push's too)
    if (
        ahead.status in ("grasp", "push")
        and not (ahead.partial or ahead.unrecognised)
        and found is not None
        and found.found
    ):
        memory.insert(
            0, FailedGroup(tuple(found.group), around_group(rest, found.group, planner.gripper), found)
        )
    if ahead.status == "push" and (paid := paid_push(rest, ahead, planner.gripper)) is not None:
        memory.insert(0, paid)
    return tuple(memory[:MEMORY_SIZE])


def without_grasped(scene, decision: PickDecision) -> Scene:
    """``scene`` without the objects ``decision``'s grasp takes (its group and what the
    physics check lifted), as the lookahead plans it."""
    gone = set(decision.group) | set(decision.expected)
    return replace(scene, objects=[o for i, o in enumerate(scene.objects) if i not in gone], group=None)
