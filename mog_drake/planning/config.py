"""The picking planner's settings as data (Drake-free), one section per concern, each with its
defaults in one place. `mog_drake.scenario` nests them as ``planner``:

* ``grasp``: GraspPlanner (Alg. 2) on one group, `GraspConfig`;
* ``loop``: the picking loop around it (Alg. 1 and its extensions), `LoopConfig`;
* ``pushes``: push-mog's consolidating pushes, `PushConfig`;
* ``lookahead``: planning the next decision while the arm moves, `LookaheadConfig`;
* ``robust``: grasps verified in a perturbed world too, `RobustConfig`.
"""

from dataclasses import dataclass, field

from mog_drake.errors import MogError
from mog_drake.geometry import DEFAULT_GROUP_RADIUS, GROUPINGS

MODES = ("mog", "sog", "push-mog")
LARGE_GROUP = 3  # objects: GraspConfig.max_physics_large caps the checks of groups this large
METHODS = ("gp", "rand-phys", "rank-phys", "rand-fil-phys", "single")  # GraspPlanner's
DIAMETER_CONDITIONS = ("paper", "columns")
# The candidate grid's most: Np x Ntheta candidates per group are evaluated at once, and past
# these the arrays outgrow memory (the paper's grid is 70 x 7).
MAX_POSITIONS, MAX_ORIENTATIONS = 10_000, 360
MAX_SEED = 2**63 - 1


@dataclass
class GraspConfig:
    method: str = "gp"
    n_positions: int = 70  # Np
    n_orientations: int = 7  # Ntheta
    max_physics: int | None = None  # stop after this many physics checks (None: never)
    # An extension, off (None) in the paper's experiments: at most this many physics checks
    # for a group of LARGE_GROUP or more objects (and never more than max_physics).
    max_physics_large: int | None = None
    # An extension, off in the paper's experiments: also try closing axes normal to the
    # group's edges, tried first among equals (see candidate_grasps).
    edge_orientations: bool = False
    # An extension, 0 (off) in the paper's experiments: a lone object is not grasped along an
    # axis from which a turn smaller than this (degrees) about the vertical lets the squeeze
    # drive it on to another final diameter (see squeeze_basins): a thin bar held end to end.
    min_squeeze_margin_deg: float = 0.0
    # An extension, off in the paper's experiments: after a failed physics check, candidates
    # whose closing axis is within AXIS_TOL of a failed one are tried only once no other axis
    # is left. A grip that slips along one axis rarely holds a few mm further along it: a
    # lone bar lying on its side ranks four end-to-end grips first, and all four slip.
    vary_axis: bool = False
    # An extension, off in the paper's experiments: a lone object's candidates are ranked by
    # squeeze-basin margin, widest first (the closing axis the squeeze forgives most), total
    # intersection area breaking ties. Area alone prefers the longest grip: a bar lying on its
    # side held end to end, which slips.
    lone_widest_basin: bool = False
    # The diameter condition the filter applies: "paper" (h0 >= h_fmin, Eq. 7) or, an
    # extension, "columns" (the frictional h0 >= h_fmin_columns, see
    # GraspEvaluation.diameter_ok_columns): it admits objects held side by side by the
    # jaws' friction.
    diameter_condition: str = "paper"

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise MogError(f"unknown planner method '{self.method}' (known: {', '.join(METHODS)})")
        if self.diameter_condition not in DIAMETER_CONDITIONS:
            raise MogError(
                f"diameter_condition must be one of {', '.join(DIAMETER_CONDITIONS)}, got {self.diameter_condition!r}"
            )
        if not (1 <= self.n_positions <= MAX_POSITIONS and 1 <= self.n_orientations <= MAX_ORIENTATIONS):
            raise MogError(
                f"n_positions must be in [1, {MAX_POSITIONS:,}] and n_orientations in [1, {MAX_ORIENTATIONS}] "
                f"(the grid's memory and time), got {self.n_positions:,} and {self.n_orientations:,}"
            )
        for key in ("max_physics", "max_physics_large"):
            if getattr(self, key) is not None and getattr(self, key) < 1:
                raise MogError(f"{key} must be at least 1 or null (no cap), got {getattr(self, key)}")
        if not 0 <= self.min_squeeze_margin_deg < 90:
            raise MogError(f"min_squeeze_margin_deg must be in [0, 90), got {self.min_squeeze_margin_deg}")


def picking_grasp() -> GraspConfig:
    """GraspPlanner as the picking loop runs it: the paper's ``gp`` with the extensions on
    (`GraspConfig` explains each) and at most 4 physics checks per group before the next group
    is tried (in the planner sweep, results/planner, GP found 135 of its 136 grasps within 3
    checks), 2 for a group of three or more objects: on 33-object tables they rarely lift
    whole, and most of a dense table's planning went into them (push-mog on the realistic
    cell, tables 0-5: groups of three found a grasp in 7 of 198 plans, 6 within 2 checks,
    for 86 of the 183 s of planning CPU; groups of four in none of 158), while pairs found 9
    of their 23 grasps at checks 2-4. A lone object is not grasped where a turn under 12
    degrees lets the squeeze carry it on to another final diameter: a thin bar held end to
    end (8 deg) can be twisted out of the jaws by the swing to the bin; every other library
    shape has 14 deg or more."""
    return GraspConfig(
        method="gp",
        max_physics=4,
        max_physics_large=2,
        edge_orientations=True,
        min_squeeze_margin_deg=12.0,
        vary_axis=True,
        lone_widest_basin=True,
    )


@dataclass
class LoopConfig:
    """The picking loop (Alg. 1) and its extensions."""

    # CreateObjGroups: "radius" (the paper's: each object's neighbours within group_radius) or
    # "conditions" (an extension: the sets of objects a grasp can close on that satisfy both
    # necessary conditions, see geometry.groups.condition_groups).
    grouping: str = "radius"
    # CreateObjGroups' radius (m): objects whose centres lie this close to one object's centre
    # form its group. The authors' robot used 35 mm, a little under half its 75 mm stroke.
    group_radius: float = DEFAULT_GROUP_RADIUS
    # mog only: a candidate seen to lift part of a larger group is a verified grasp of that
    # part, taken once no larger group is left to try.
    partial_lifts: bool = True
    # A group found to have no grasp is not planned again while every object within its reach
    # lies where it was (the same checks would give the same verdicts).
    remember_failures: bool = True
    # Before the run ends on "no grasp found", plan every group again with up to 12 more
    # physics checks each, 48 in all.
    last_resort: bool = True
    # sog only: a grasp is taken only if its check lifts the one object alone; a check that
    # lifts a neighbour along is tried no further (the next candidate, then the next object).
    # The paper's single-object baseline took 1.12 objects per successful grasp, its extras
    # by accident ("uncertainty can sometimes aid [it] in grasping more than one object");
    # off, a fifth of our single-object grasps are planned to lift a neighbour too. The last
    # resort still takes any grasp of the object.
    sog_alone: bool = False
    # After a grasp that took none of its objects, the object nearest each of its open jaws
    # (within 8 mm) may be what a plate came down on: later grasps keep their jaws its gap
    # plus 2 mm off it, until it is taken (`picking.tally_suspects`). Without it, only the
    # missed jaws' own footprints are kept clear, for the last three misses. On six tables of
    # the paper's cell in a stiffer world it cut repeated stops 22 -> 8 (mog) and, with every
    # suspect kept until taken, 18 -> 12 (sog), at no measured cost (docs/experiments.md).
    wary_neighbours: bool = True

    def check(self) -> None:
        if self.grouping not in GROUPINGS:
            raise MogError(
                f"planner.loop.grouping must be one of {', '.join(GROUPINGS)}, got {self.grouping!r}"
            )
        if not 0 < self.group_radius <= 0.2:
            raise MogError(f"planner.loop.group_radius must be in (0, 0.2] m, got {self.group_radius}")


@dataclass
class PushConfig:
    """push-mog (an extension: see `mog_drake.planning.pushing`): a push that brings a lone
    object to another, simulated, then the grasp it sets up."""

    max_per_table: int = 12
    # Pushes simulated per decision (each followed by the plan of the grasp it sets up).
    checks: int = 2
    speed: float = 0.05  # the push's mean speed (m/s)
    # How far apart (centres, m) an object and the one it is pushed to may start.
    reach: float = 0.12
    # Pushes are considered only when Alg. 1's grasp lifts fewer objects than this (in its
    # physics check): each consideration simulates pushes and grasps (6-10 s of CPU, planned
    # ahead by the lookahead when it is in time). With 2, lone objects are paired; a pair made
    # a trio would add 15-20 % (3 objects in 8-8.5 s against 2 in 6.5 s).
    below: int = 2
    # After a push, grasp the group it set up at once, where the physics check left it, with
    # no new image: the arm goes up, opens its jaws and on to that grasp instead of back to
    # the observe pose to look again. Off: it looks again, and plans anew.
    then_grasp: bool = True
    # The rule: push when the objects per second of robot time expected from the push and the
    # grasp it sets up beat the grasp now. The robot time a push adds besides its line (s),
    # and of a grasp (observe pose to observe pose, s), as measured on seed-0 tables: grasps
    # 6.3-6.7 s; a push looked at again 3.1 s plus its line (set 3.1 with then_grasp off),
    # one grasped at once about 1.5 s plus its line.
    push_time_s: float = 1.5
    grasp_time_s: float = 6.5

    def check(self) -> None:
        if self.max_per_table < 0 or self.checks < 0 or self.below < 0:
            raise MogError("planner.pushes: max_per_table, checks and below must be >= 0")
        if not 0 < self.speed <= 0.25:
            raise MogError(f"planner.pushes.speed must be in (0, 0.25] m/s, got {self.speed}")
        if not 0 < self.reach <= 0.2:
            raise MogError(f"planner.pushes.reach must be in (0, 0.2] m, got {self.reach}")
        if not (0 < self.push_time_s <= 60 and 0 < self.grasp_time_s <= 60):
            raise MogError("planner.pushes: push_time_s and grasp_time_s must be in (0, 60] s")


@dataclass
class LookaheadConfig:
    """Planning ahead (with loop.remember_failures): once a grasp is decided, the next decision
    is planned on the same image without the objects it grasps, on a second worker, while the
    arm executes it. In the next image, every group whose surroundings are where they were
    (3 mm) is replayed from that plan with no physics: its failure, or its grasp. Only the
    groups the grasp disturbed are simulated again. In push-mog it considers pushes too: a
    push that paid is replayed, with its grasp. In sog the object whose grasp it found is
    tried first (`next_pick`): it drew that object at random, one image earlier, as the
    decision itself would have. A lookahead not done when the
    next image comes is dropped (reading its verdicts as they came, and waiting for it, were
    tried and did not pay: docs/experiments.md)."""

    enabled: bool = True


@dataclass
class RobustConfig:
    """Robust grasps (`mog_drake.planning.robust`): before any physics, the grasp's geometry in
    ``screen`` perturbed worlds, every one of which must keep the open jaws off every object
    and each group object between them; after the nominal check passes, ``samples`` checks
    of a perturbed world, of which ``required`` (0: all) must lift the group. Off (0 screen,
    0 samples) by default, and in the faithful reproduction of the paper."""

    samples: int = 0
    required: int = 0
    screen: int = 0
    # The perturbations: what the planner is unsure of (docs/physics.md, the realistic cell).
    shift_sigma: float = 0.003  # m per axis, one shift of every object: the camera's calibration
    pose_sigma: float = 0.0005  # m per axis, each object's own: perception's fit
    yaw_sigma_deg: float = 0.5  # each object's own
    friction_spread: float = 0.3  # each friction coefficient x U(1 - s, 1 + s)
    mass_spread: float = 0.2  # each object's mass x U(1 - s, 1 + s)
    seed: int = 0
    # Above 0, where no robust grasp is left the last resort (`picking.next_pick`) first takes
    # a grasp whose open jaws this share of the screen's worlds keeps clear (the nominal check
    # after the screen), before one the nominal check alone passes.
    relaxed_share: float = 0.0

    def check(self) -> None:
        if not 0 <= self.samples <= 16 or not 0 <= self.required <= self.samples:
            raise MogError("planner.robust: samples must be in [0, 16] and required in [0, samples]")
        if not 0 <= self.screen <= 64:
            raise MogError(f"planner.robust.screen must be in [0, 64], got {self.screen}")
        for key, most in (("shift_sigma", 0.02), ("pose_sigma", 0.02), ("yaw_sigma_deg", 10.0)):
            if not 0 <= getattr(self, key) <= most:
                raise MogError(f"planner.robust.{key} must be in [0, {most:g}], got {getattr(self, key)}")
        for key in ("friction_spread", "mass_spread"):
            if not 0 <= getattr(self, key) < 1:
                raise MogError(f"planner.robust.{key} must be in [0, 1), got {getattr(self, key)}")
        if not 0 <= self.seed <= MAX_SEED:
            raise MogError(f"planner.robust.seed must be a whole number >= 0, got {self.seed}")
        if not 0 <= self.relaxed_share < 1:
            raise MogError(f"planner.robust.relaxed_share must be in [0, 1), got {self.relaxed_share}")


@dataclass
class PlannerSpec:
    # mog (Alg. 1) | sog (the single-object baseline) | push-mog (Alg. 1 with consolidating
    # pushes, an extension)
    mode: str = "mog"
    seed: int = 0
    grasp: GraspConfig = field(default_factory=picking_grasp)
    loop: LoopConfig = field(default_factory=LoopConfig)
    pushes: PushConfig = field(default_factory=PushConfig)
    lookahead: LookaheadConfig = field(default_factory=LookaheadConfig)
    robust: RobustConfig = field(default_factory=RobustConfig)

    def check(self) -> None:
        """Refuses a setting that would only fail once the robot is running."""
        if self.mode not in MODES:
            raise MogError(f"planner.mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        if not 0 <= self.seed <= MAX_SEED:
            raise MogError(f"planner.seed must be a whole number >= 0, got {self.seed}")
        if self.grasp.method == "single":  # picking chooses its objects itself
            methods = ", ".join(m for m in METHODS if m != "single")
            raise MogError(f"planner.grasp.method must be one of {methods}, got 'single'")
        try:
            self.grasp.__post_init__()
        except MogError as e:
            raise MogError(f"planner.grasp: {e}") from None
        self.loop.check()
        self.pushes.check()
        self.robust.check()
