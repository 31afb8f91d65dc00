"""What the application's systems pass each other, on their ports and in their state: the
perceived scene (`Perceived`), a change check's answer (`Checked`), the planner's decision
(`Decision`), and a worker's slot (`Slot`). Values replaced, never changed (`Immutable`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mog_drake.planning.decision import PickDecision
from mog_drake.systems.jobs import Job


class Immutable:
    """State values that are replaced, never changed in place. Drake copies abstract state
    (every unrestricted update copies the whole state); a deep copy of a perceived Scene or a
    motion plan per 10 ms tick cost a third of a pick run's wall time, so copies share."""

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self


@dataclass
class Perceived(Immutable):
    """A perceived scene: its request ``counter``; the simulated times of the request and of
    the result becoming visible; the job's wall time; whether it retakes a request whose
    table changed before its decision was used (``retake``); and the depth image it was
    perceived from (for the change check)."""

    counter: int = -1
    scene: object = None
    t_request: float = 0.0
    t_visible: float = 0.0
    wall_time: float = 0.0
    retake: bool = False
    depth: object = None
    wall_total: float = 0.0  # wall time of every perception job so far (s)


@dataclass
class Checked(Immutable):
    """The answer to a change check of request ``counter``: whether the table in view now
    differs from the image that request was perceived from (``pixels`` that changed)."""

    counter: int = -1
    changed: bool = False
    pixels: int = 0


@dataclass
class Decision(Immutable):
    counter: int = -1
    decision: PickDecision | None = None
    objects_seen: int = 0
    blobs_seen: int = 0  # unrecognised blobs in the image it was planned from
    recent: tuple = ()  # the last grasps issued, not to be repeated
    failures: tuple = ()  # groups found to have no grasp (see next_pick)
    unrecognised_grasps: int = 0  # grasps of unrecognised blobs issued in a row
    rng: np.random.Generator | None = None  # the planner's random draws, after this decision
    t_request: float = 0.0  # simulated time the scene became visible (the planning request)
    t_visible: float = 0.0  # simulated time this decision became visible
    wall_time: float = 0.0  # the planning job's wall time (s)
    cpu_time: float = 0.0  # the planning job's CPU time (s)
    previous: Decision | None = None  # the state this one was planned from
    pushes: int = 0  # push-mog: pushes decided so far, this one included
    # (shape, x, y) of the objects this decision's grasp means to take, and the failed grasps
    # per object as of its image ((shape, x, y, count): see tally_misses).
    targets: tuple = ()
    misses: tuple = ()
    # The last few grasps that took none of their objects (`picking.missed`), as of its image:
    # their jaws' footprints are kept clear (`planner.jaw_obstacles`).
    missed_grasps: tuple = ()
    # Objects a missed grasp's jaws may have come down on ((shape, x, y, margin): see
    # tally_suspects), as of its image; with planner.loop.wary_neighbours.
    suspects: tuple = ()
    # The lookahead's memory for this plan: "used" (visible at its image), "dropped" (not in
    # time), or "" (none ran).
    lookahead: str = ""


@dataclass
class Slot(Immutable):
    job: Job | None = None
    pending: tuple | None = None  # (request, depth, when, first look): waiting for a still table
