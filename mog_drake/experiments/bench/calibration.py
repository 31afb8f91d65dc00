"""Camera calibration from a printed board, checked in simulation (`mog-drake bench calibration`):
the realistic cell's drawn camera errors, and ten times them, recovered from a rendered board."""

from __future__ import annotations

import statistics
from dataclasses import replace


def bench_calibration(scenario=None, draws: int = 20, large: int = 5, seed: int = 0) -> list[dict]:
    """Per drawn world (tables ``seed`` .. ``seed + draws - 1`` at the scenario's calibration
    error, the next ``large`` at ten times it): the camera's pose error before calibration
    (the scenario's camera.X_PB against the rendering camera), and after (the pose solved from
    the board against it), in mm and deg; the fit's figures."""
    from mog_drake.camera import camera_pose
    from mog_drake.hardware.calibration import board_in_table, pose_error, solve
    from mog_drake.scenario import ClutteredScene, load_scenario
    from mog_drake.station.board import board_frame

    base = load_scenario(scenario or "realistic")
    rows = []
    for k in range(seed, seed + draws + large):
        scale = 1.0 if k < seed + draws else 10.0
        real = replace(
            base.realism,
            camera_offset=base.realism.camera_offset * scale,
            camera_tilt_deg=base.realism.camera_tilt_deg * scale,
        )
        sc = replace(base, scene=ClutteredScene(seed=k), realism=real)
        rgb, depth, intrinsics, truth = board_frame(sc)
        cal = solve(rgb, depth, intrinsics, board_in_table(0.0, 0.0, 0.0))
        before, after = pose_error(camera_pose(sc.camera), truth), pose_error(cal.X_TC, truth)
        rows.append(
            {
                "table_seed": k,
                "error_scale": scale,
                "before_mm": before[0] * 1e3,
                "before_deg": before[1],
                "after_mm": after[0] * 1e3,
                "after_deg": after[1],
                "reprojection_px": cal.reprojection_px,
                "depth_rms_mm": cal.depth_residual * 1e3,
            }
        )
    return rows


def calibration_text(rows: list[dict]) -> str:
    lines = []
    for scale in dict.fromkeys(r["error_scale"] for r in rows):
        rs = [r for r in rows if r["error_scale"] == scale]
        mm, deg = [r["after_mm"] for r in rs], [r["after_deg"] for r in rs]
        lines.append(
            f"{len(rs)} draws at {scale:g}x the scenario's calibration error (before: median "
            f"{statistics.median(r['before_mm'] for r in rs):.2f} mm, {statistics.median(r['before_deg'] for r in rs):.3f} deg): "
            f"after, median {statistics.median(mm):.2f} mm and {statistics.median(deg):.3f} deg, worst "
            f"{max(mm):.2f} mm and {max(deg):.3f} deg"
        )
    return "\n".join(lines)
