"""Settings of the application systems (the scenario's ``controller``, ``motion`` and
``latency`` sections), as data: the systems that use them and `mog_drake.scenario` import
them from here. (No ``from __future__ import annotations``: Drake's YAML reads the field
types.)"""

from dataclasses import dataclass

from mog_drake.errors import MogError

LATENCY_MODES = ("measured", "cpu", "fixed")


def in_range(value, key: str, lo: float, hi: float, lo_open: bool = True) -> None:
    """Refuses ``value`` outside (lo, hi] ([lo, hi] with ``lo_open=False``), naming ``key``."""
    ok = (lo < value if lo_open else lo <= value) and value <= hi
    if not ok:
        left = "(" if lo_open else "["
        raise MogError(f"{key} must be in {left}{lo:g}, {hi:g}], got {value!r}")


def box_bounds(values, key: str, n: int) -> None:
    """Refuses a box that is not ``n`` numbers of (min, max) pairs with min < max."""
    if len(values) != n or any(values[i] >= values[i + 1] for i in range(0, n, 2)):
        got = list(values) if len(values) <= 2 * n else f"{len(values):,} numbers"
        raise MogError(f"{key} must be {n} numbers (min, max pairs with min < max), got {got}")


@dataclass
class LatencyConfig:
    """How long perception and planning take in simulated time: ``measured`` (each job's own
    wall time), ``cpu`` (each job's CPU time) or ``fixed`` (``perception_s`` and
    ``planning_s`` for every job)."""

    mode: str = "measured"
    perception_s: float = 0.3
    planning_s: float = 2.0
    # s, with mode cpu: the CPU time of the reference physics check (`sim.reference`; each
    # picking run records its machine's) on the computer to model. Each job's CPU time is
    # scaled by it over this machine's, so that runs on machines of other speeds pair;
    # perception's by the same factor, though its numpy may scale otherwise than Drake's
    # physics. 0: this machine's CPU time as it is.
    cpu_reference_s: float = 0.0

    def of(self, stage: str) -> float | None:
        """The fixed latency of ``stage`` ("perception" or "planning"), None when measured."""
        if self.mode == "fixed":
            return getattr(self, f"{stage}_s")
        return None

    def check(self) -> None:
        if self.mode not in LATENCY_MODES:
            raise MogError(f"latency.mode must be one of {', '.join(LATENCY_MODES)}, got {self.mode!r}")
        for key in ("perception_s", "planning_s"):
            in_range(getattr(self, key), f"latency.{key}", 0, 600, lo_open=False)
        in_range(self.cpu_reference_s, "latency.cpu_reference_s", 0, 60, lo_open=False)


@dataclass
class ControllerConfig:
    """The controller's timing (s)."""

    # Between the application systems' updates (perception, planner, controller).
    period: float = 0.01
    # The jaws close for as long as a full close takes at the gripper's speed, plus this.
    close_margin: float = 0.2
    open_time: float = 0.35  # the jaws open over the bin
    settle_time: float = 0.2  # at the start, before the first image
    max_unreachable: int = 3  # unreachable grasps in a row that end the run
    # After the jaws open over the bin the arm goes back to the observe pose (the paper's
    # cycle). Off (the default): where the arm over the bin hides none of the table, the
    # table is checked from there and the arm goes straight on to the next grasp or push,
    # 1.4 s of its 6.7 s cycle saved.
    return_home: bool = False
    # N: the guarded descent. Once the arm is above the grasp, the wrist's force (the station's
    # ur5.wrist_force: the simulated contact forces on the gripper, or the UR5's
    # getActualTCPForce) is measured from its value there; past this the arm stops and backs
    # out, the attempt failed (docs/physics.md: a plate that comes down on an object). 0: off.
    # Above the 25 N to which a CB3 detects its TCP force (its manual, the safety functions),
    # so the estimate's own error does not trip it; far under the force limit of its safety
    # configuration, which would protective-stop the arm.
    guard_force: float = 40.0

    def check(self) -> None:
        in_range(self.period, "controller.period (s)", 0, 1.0)
        in_range(self.guard_force, "controller.guard_force (N)", 0, 1000, lo_open=False)
        for key in ("close_margin", "open_time", "settle_time"):
            in_range(getattr(self, key), f"controller.{key} (s)", 0, 60, lo_open=False)


@dataclass
class MotionConfig:
    hover: float = 0.12  # m, palm height above the grasp height before descending
    lift: float = 0.15  # m
    # m, fingertips above the bin rim. At 0.17 the arm over the bin hides none of the table
    # (every one of 300 sampled carries; at 0.12, 47 %), so the arm can go on from there
    # (ControllerConfig.return_home); the carry takes no longer.
    bin_clearance: float = 0.17
    levels: int = 5  # IK points on a vertical line
    # While objects are held (lift, travel to the bin) the arm moves at this fraction of its
    # joint speed and acceleration limits: objects carried by friction stay put.
    carry_scale: float = 0.5

    def check(self) -> None:
        in_range(self.carry_scale, "motion.carry_scale", 0, 1)
