"""One RGB-D frame of the calibration board (`mog_drake.hardware.calibration`): recorded,
from the real camera, or rendered by the simulated station with the board on its table."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mog_drake.errors import MogError
from mog_drake.hardware.calibration import board_in_table


def board_frame(scenario, frames: str | None = None, board_at=(0.0, 0.0, 0.0)):
    """(rgb, depth, intrinsics, truth) of one frame of the board: recorded (``frames``, a
    `record_frame` folder: its first frame), from the scenario's real camera (hardware
    scenarios), or rendered by its simulated station with the board at ``board_at`` (x, y m,
    yaw rad) on an empty table. ``truth``: in simulation, the rendering camera's pose (X_TC,
    the realistic cell's drawn calibration error in it); else None."""
    from mog_drake.hardware.config import ReplaySource

    if not frames and scenario.hardware.enabled and isinstance(scenario.hardware.camera, ReplaySource):
        frames = scenario.hardware.camera.dir
    if frames:
        files = sorted(Path(frames).glob("frame_*.npz"))
        if not files:
            raise MogError(f"no recorded frames (frame_*.npz) in {frames}")
        from mog_drake.hardware.cameras import ReplayCamera

        cam = ReplayCamera(frames)
        ctx = cam.CreateDefaultContext()
        rgb = cam.GetOutputPort("camera.rgb_image").Eval(ctx).data[..., :3]
        depth = cam.GetOutputPort("camera.depth_image").Eval(ctx).data[..., 0]
        return np.array(rgb), np.array(depth), cam.intrinsics, None
    if scenario.hardware.enabled:
        from pydrake.systems.analysis import Simulator

        from mog_drake.hardware.cameras import RealSenseCamera

        cam = RealSenseCamera(scenario.camera.width, scenario.camera.height, scenario.hardware.camera.fps)
        try:
            sim = Simulator(cam)
            sim.AdvanceTo(0.5)  # a few frames: the exposure settles
            ctx = sim.get_context()
            rgb = cam.GetOutputPort("camera.rgb_image").Eval(ctx).data[..., :3]
            depth = cam.GetOutputPort("camera.depth_image").Eval(ctx).data[..., 0]
            return np.array(rgb), np.array(depth), cam.intrinsics, None
        finally:
            cam.stop()
    from pydrake.math import RigidTransform, RollPitchYaw

    from mog_drake.camera import camera_pose
    from mog_drake.scenes import Scene, default_library
    from mog_drake.station import MakeStation, render_still

    X_TB = board_in_table(*board_at)
    empty = Scene([], default_library(), table=tuple(scenario.table))
    station, handles = MakeStation(scenario, empty, board=X_TB)
    rgb, depth = render_still(scenario, station)
    w = scenario.realism.draw(getattr(scenario.scene, "seed", 0), 0)
    X_true = RigidTransform(w.camera_offset) @ RigidTransform(camera_pose(scenario.camera))
    X_true = X_true @ RigidTransform(RollPitchYaw(w.camera_tilt), np.zeros(3))
    return np.array(rgb)[..., :3], np.array(depth), handles.camera_intrinsics, X_true.GetAsMatrix4()
