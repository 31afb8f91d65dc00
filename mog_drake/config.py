"""Settings of the application systems (the scenario's ``controller``, ``motion`` and
``latency`` sections), as data: the systems that use them and `mog_drake.scenario` import
them from here. (No ``from __future__ import annotations``: Drake's YAML reads the field
types.)"""

from dataclasses import dataclass

LATENCY_MODES = ("measured", "cpu", "fixed")


@dataclass
class LatencyConfig:
    """How long perception and planning take in simulated time: ``measured`` (each job's own
    wall time), ``cpu`` (each job's CPU time) or ``fixed`` (``perception_s`` and
    ``planning_s`` for every job)."""

    mode: str = "measured"
    perception_s: float = 0.3
    planning_s: float = 2.0

    def of(self, stage: str) -> float | None:
        """The fixed latency of ``stage`` ("perception" or "planning"), None when measured."""
        if self.mode == "fixed":
            return getattr(self, f"{stage}_s")
        return None


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
