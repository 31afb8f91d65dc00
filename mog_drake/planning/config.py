"""The picking planner's settings as data (Drake-free): what `next_pick`, the grasp planner and
its physics check read, with their defaults in one place. `mog_drake.scenario` nests it as
``planner``."""

import math
from dataclasses import dataclass

from mog_drake.errors import MogError
from mog_drake.geometry import DEFAULT_GROUP_RADIUS, GROUPINGS
from mog_drake.planning.planner import DIAMETER_CONDITIONS, METHODS, PlannerConfig

MODES = ("mog", "sog", "push-mog")


@dataclass
class PlannerSpec:
    method: str = "gp"  # gp | rand-phys | rank-phys | rand-fil-phys
    # mog (Alg. 1) | sog (the single-object baseline) | push-mog (Alg. 1 with consolidating
    # pushes, an extension: see next_pick)
    mode: str = "mog"
    n_positions: int = 70
    n_orientations: int = 7
    seed: int = 0
    # Physics checks per group before the next group is tried (0: no cap). Groups that have a
    # grasp show it early: in the planner sweep (results/planner) GP found 135 of its 136
    # grasps within 3 checks.
    max_physics_per_group: int = 4
    # mog only, an extension of Alg. 1: a candidate seen to lift part of a larger group is a
    # verified grasp of that part, taken once no larger group is left to try.
    partial_lifts: bool = True
    # Also try closing axes normal to the group's edges (first among equal-area candidates):
    # grid orientations k pi / n alone pinch a lone thin bar across its corners.
    edge_orientations: bool = True
    # A lone object is not grasped where a turn under this many degrees lets the squeeze carry
    # it on to another final diameter: a thin bar held end to end (8 deg) can be twisted out of
    # the jaws by the swing to the bin. Every other library shape has 14 deg or more.
    min_squeeze_margin_deg: float = 12.0
    # After a failed physics check, try a new closing axis before other points on a failed one
    # (an extension; the paper's experiments go down the ranked list).
    vary_axis: bool = True
    # A lone object is gripped along the axis the squeeze forgives most (widest squeeze basin,
    # then total area): area alone grips a bar lying on its side end to end (an extension).
    lone_widest_basin: bool = True
    # A group found to have no grasp is not planned again while every object within its reach
    # lies where it was (an extension of Alg. 1: the same checks would give the same verdicts).
    remember_failures: bool = True
    # CreateObjGroups' radius (m): objects whose centres lie this close to one object's centre
    # form its group. The authors' robot used 35 mm, a little under half its 75 mm stroke.
    group_radius: float = DEFAULT_GROUP_RADIUS
    # CreateObjGroups: "radius" (the paper's: each object's neighbours within group_radius) or
    # "conditions" (an extension: the sets of objects a grasp can close on that satisfy both
    # necessary conditions, see geometry.groups.condition_groups).
    grouping: str = "radius"
    # Before the run ends on "no grasp found", plan every group again with up to 12 more
    # physics checks each, 48 in all (an extension).
    last_resort: bool = True
    # The filter's diameter condition: "paper" (Eq. 7) or "columns" (an extension: objects
    # side by side across the jaws' width, held by their friction; see
    # GraspEvaluation.diameter_ok_columns). `eval conditions`: 92.0 % of the physics
    # negatives still rejected (92.9 % with the paper's), 50 false negatives instead of 70.
    diameter_condition: str = "paper"
    # Plan ahead (an extension; mog and push-mog, with remember_failures): once a grasp is
    # decided, the next decision is planned on the same image without the objects it grasps,
    # on a second worker, while the arm executes it. In the next image, every group whose
    # surroundings are where they were (3 mm) is replayed from that plan with no physics: its
    # failure, or its grasp. Only the groups the grasp disturbed are simulated again. In
    # push-mog it considers pushes too: a push that paid is replayed, with its grasp.
    lookahead: bool = True
    # When the next image comes before the lookahead is done (measured latencies), its plan
    # starts at once and reads the lookahead's board (mog_drake.planning.board): the verdicts
    # visible by then in simulated time are replayed, and a group the lookahead is simulating
    # then is waited for, not simulated twice (off: the lookahead is dropped). It never
    # simulates more than a plan without them. (Waiting for the whole lookahead instead was
    # tried and measured worse: docs/experiments.md.)
    merge_lookahead: bool = True
    # push-mog: pushes per table at most; pushes simulated per decision (each followed by the
    # plan of the grasp it sets up); the push's mean speed (m/s); how far apart (centres, m)
    # an object and the one it is pushed to may start.
    max_pushes: int = 12
    push_checks: int = 2
    push_speed: float = 0.05
    push_reach: float = 0.12
    # Pushes are considered only when Alg. 1's grasp lifts fewer objects than this (in its
    # physics check): each consideration simulates pushes and grasps (6-10 s of CPU, planned
    # ahead by the lookahead when it is in time). With 2, lone objects are paired; a pair made
    # a trio would add 15-20 % (3 objects in 8-8.5 s against 2 in 6.5 s).
    push_below: int = 2
    # After a push, grasp the group it set up at once, where the physics check left it, with
    # no new image: the arm goes up, opens its jaws and on to that grasp instead of back to
    # the observe pose to look again. Off: it looks again, and plans anew.
    push_then_grasp: bool = True
    # push-mog's rule: push when the objects per second of robot time expected from the push
    # and the grasp it sets up beat the grasp now. The robot time a push adds besides its line
    # (s), and of a grasp (observe pose to observe pose, s), as measured on seed-0 tables:
    # grasps 6.3-6.7 s; a push looked at again 3.1 s plus its line (set 3.1 with
    # push_then_grasp off), one grasped at once about 1.5 s plus its line.
    push_time_s: float = 1.5
    grasp_time_s: float = 6.5
    # mog and push-mog (an extension): CPU seconds a decision may search for a larger group
    # once it holds a verified grasp (a partial lift); past them it takes that grasp (0: no
    # limit). Beside the arm, planning is free while the arm carries and returns (about 5 s);
    # every second past that is a second the arm waits, while the larger group it might find
    # is a long shot (a multi-object check on a full table lifts its whole group in about 1 of
    # 8 tries). Off by default: replaying the planner on 4 seeded tables (`bench replanning
    # --budget 3`), 3 s cut the decisions' CPU past 5 s from 29.8 to 2.6 s at 1.57 -> 1.52
    # objects per decision, but in the pick loop (table 0, mog) it halved the wait and cost
    # a quarter of the objects per grasp (1.74 -> 1.32) and 17 % of PPH: a 4-object group's
    # first check already costs about 2 s, so 3 s left one check for it.
    decision_budget_s: float = 0.0

    def check(self) -> None:
        """Refuses a setting that would only fail once the robot is running."""
        methods = [m for m in METHODS if m != "single"]  # picking chooses its objects itself
        if self.method not in methods:
            raise MogError(f"planner.method must be one of {', '.join(methods)}, got {self.method!r}")
        if self.mode not in MODES:
            raise MogError(f"planner.mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        if self.max_physics_per_group < 0 or self.n_positions < 1 or self.n_orientations < 1:
            raise MogError("planner: max_physics_per_group must be >= 0, n_positions and n_orientations >= 1")
        if not 0 <= self.min_squeeze_margin_deg < 90:
            raise MogError(
                f"planner: min_squeeze_margin_deg must be in [0, 90), got {self.min_squeeze_margin_deg}"
            )
        if not 0 <= self.decision_budget_s <= 600:
            raise MogError(f"planner: decision_budget_s must be in [0, 600] s, got {self.decision_budget_s}")
        if not 0 < self.group_radius <= 0.2:
            raise MogError(f"planner: group_radius must be in (0, 0.2] m, got {self.group_radius}")
        if self.max_pushes < 0 or self.push_checks < 0 or self.push_below < 0:
            raise MogError("planner: max_pushes, push_checks and push_below must be >= 0")
        if not 0 < self.push_speed <= 0.25:
            raise MogError(f"planner: push_speed must be in (0, 0.25] m/s, got {self.push_speed}")
        if not 0 < self.push_reach <= 0.2:
            raise MogError(f"planner: push_reach must be in (0, 0.2] m, got {self.push_reach}")
        if not (0 < self.push_time_s <= 60 and 0 < self.grasp_time_s <= 60):
            raise MogError("planner: push_time_s and grasp_time_s must be in (0, 60] s")
        if self.diameter_condition not in DIAMETER_CONDITIONS:
            raise MogError(
                f"planner.diameter_condition must be one of {', '.join(DIAMETER_CONDITIONS)}, got {self.diameter_condition!r}"
            )
        if self.grouping not in GROUPINGS:
            raise MogError(f"planner.grouping must be one of {', '.join(GROUPINGS)}, got {self.grouping!r}")

    def grasp_planner(self) -> PlannerConfig:
        """The GraspPlanner's (Alg. 2) share of these settings."""
        return PlannerConfig(
            method=self.method,
            n_positions=self.n_positions,
            n_orientations=self.n_orientations,
            max_physics=self.max_physics_per_group or None,
            edge_orientations=self.edge_orientations,
            min_squeeze_margin=math.radians(self.min_squeeze_margin_deg),
            vary_axis=self.vary_axis,
            lone_widest_basin=self.lone_widest_basin,
            diameter=self.diameter_condition,
        )
