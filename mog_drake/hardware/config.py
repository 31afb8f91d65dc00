"""The real cell's settings (the scenario's ``hardware:`` section) and its camera sources,
chosen by YAML tag. (No ``from __future__ import annotations``: Drake's YAML reads the field
types.)"""

import math
from dataclasses import dataclass, field
from typing import Union

from mog_drake.config import box_bounds, in_range
from mog_drake.errors import MogError


@dataclass
class RealSenseSource:
    """An Intel RealSense (pyrealsense2), colour and depth aligned to colour."""

    fps: int = 30

    def check(self) -> None:
        in_range(self.fps, "hardware.camera.fps", 0, 300)


@dataclass
class ReplaySource:
    """Recorded RGB-D frames (frame_*.npz) from ``dir``, one per ``frame_period`` s (the last
    one held; default: the first one held)."""

    dir: str = ""
    frame_period: float = 1e9

    def check(self) -> None:
        if not self.dir.strip():
            raise MogError("hardware.camera.dir must name a folder of recorded frames")
        in_range(self.frame_period, "hardware.camera.frame_period (s)", 0, 1e9)


@dataclass
class HardwareSpec:
    """The real robot (see docs/hardware.md). ``enabled`` selects it."""

    enabled: bool = False
    robot_ip: str = ""  # required: the station refuses to start without it
    gripper_port: int = 63352
    camera: Union[RealSenseSource, ReplaySource] = field(default_factory=RealSenseSource)  # noqa: UP007
    dry_run: bool = False  # log every command instead of sending it
    command_log: str = "out/dry_run.jsonl"  # dry run: JSON lines of the commands, one run's
    # Palm box (xmin, xmax, ymin, ymax, zmin, zmax; m, table frame); the fingertips stay inside
    # it in x and y, and above the table top.
    workspace: list[float] = field(default_factory=lambda: [-0.45, 0.45, -0.45, 0.55, 0.035, 0.65])
    max_joint_speed: float = 1.5  # rad/s in wall-clock time: a target implying more is refused
    # s of motion at max_joint_speed the stream may run ahead of the wall clock (PC jitter).
    burst_window: float = 0.03
    # m: every link frame (shoulder, elbow, wrists, flange) at least this far above the table top
    # (about a link's radius; the pick's motions keep 0.15 m or more).
    link_clearance: float = 0.05
    link_box: list[float] = field(default_factory=list)  # optional box for every link frame
    servo_period: float = 0.01  # s, servoJ streaming period (the controller's period)
    stale_after: float = 0.1  # s without a new RTDE timestamp before the robot state is stale
    gripper_timeout: float = 1.0  # s, hard deadline of one gripper request
    gripper_activation_timeout: float = 5.0  # s for the gripper's activation (STA 3)
    gripper_move_timeout: float = 5.0  # s for a gripper move to end (OBJ non-zero)

    def check(self) -> None:
        if not 1 <= self.gripper_port <= 65535:
            raise MogError(f"hardware.gripper_port must be a TCP port (1-65535), got {self.gripper_port}")
        in_range(self.max_joint_speed, "hardware.max_joint_speed (rad/s)", 0, 2 * math.pi)
        in_range(self.servo_period, "hardware.servo_period (s)", 0.001, 0.1, lo_open=False)
        in_range(self.burst_window, "hardware.burst_window (s)", 0, 1.0)
        in_range(self.stale_after, "hardware.stale_after (s)", 0, 10.0)
        in_range(self.link_clearance, "hardware.link_clearance (m)", 0, 1.0, lo_open=False)
        # Each a wait on the gripper: 0 would fault every request, and nothing may wait past 60 s.
        in_range(self.gripper_timeout, "hardware.gripper_timeout (s)", 0, 20.0)
        in_range(self.gripper_activation_timeout, "hardware.gripper_activation_timeout (s)", 0, 60.0)
        in_range(self.gripper_move_timeout, "hardware.gripper_move_timeout (s)", 0, 60.0)
        box_bounds(self.workspace, "hardware.workspace", 6)
        if self.link_box:
            box_bounds(self.link_box, "hardware.link_box", 6)
        self.camera.check()
