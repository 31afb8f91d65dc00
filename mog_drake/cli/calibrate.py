"""`mog-drake calibrate`: the camera's pose in the table frame from a printed board."""

from __future__ import annotations

import math

from mog_drake.cli.common import emit


def add_parsers(sub) -> None:
    cal = sub.add_parser(
        "calibrate", help="the camera's pose in the table frame from a printed ChArUco board"
    ).add_subparsers(dest="calibrate_command", required=True)
    sp = cal.add_parser("board", help="write the board to print, at true scale, its size on it")
    sp.add_argument("-o", "--output", required=True, help="file to write: .pdf or .png (300 dpi), an A4 page")
    sp.add_argument("--json", action="store_true", help="print one JSON document instead of text")
    sp.set_defaults(func=cmd_board)
    for name, helptext in (
        (
            "camera",
            "solve the camera's pose from one frame of the board; print it as the scenario's camera.X_PB",
        ),
        ("check", "how far the scenario's camera.X_PB is from the pose one frame of the board gives"),
    ):
        sp = cal.add_parser(name, help=helptext)
        sp.add_argument(
            "--scenario",
            help="scenario YAML or a shipped one's name: its camera (a RealSense on a hardware scenario; "
            "in simulation its station renders the board) and its camera.X_PB (default: the built-in one)",
        )
        sp.add_argument(
            "--frames",
            metavar="DIR",
            help="a recorded frame's folder (record_frame) instead of the camera (default: none)",
        )
        sp.add_argument(
            "--board-at",
            type=float,
            nargs=3,
            metavar=("X_MM", "Y_MM", "YAW_DEG"),
            default=(0.0, 0.0, 0.0),
            help="where the board's centre lies on the table and its turn; its long side along the table's x "
            "at yaw 0, its printed top edge toward +y (default: 0 0 0)",
        )
        sp.add_argument(
            "--seed",
            type=int,
            help="simulation: the table seed whose drawn camera error is rendered (default: the scenario's)",
        )
        sp.add_argument("--json", action="store_true", help="print one JSON document instead of text")
        sp.set_defaults(func=cmd_camera if name == "camera" else cmd_check)


def _solve(args):
    from mog_drake.hardware.calibration import board_in_table, solve
    from mog_drake.scenario import load_scenario, with_overrides
    from mog_drake.station.board import board_frame

    sc = with_overrides(load_scenario(args.scenario), args.scenario, seed=args.seed)
    x, y, yaw = args.board_at
    at = (x / 1e3, y / 1e3, math.radians(yaw))
    rgb, depth, intrinsics, truth = board_frame(sc, args.frames, at)
    return sc, solve(rgb, depth, intrinsics, board_in_table(*at)), truth


def _figures(cal, truth) -> tuple[dict, list[str]]:
    from mog_drake.hardware.calibration import pose_error

    doc = {
        "X_TC": cal.X_TC.tolist(),
        "corners": cal.corners,
        "reprojection_px": cal.reprojection_px,
        "depth_rms_mm": cal.depth_residual * 1e3,
    }
    lines = [
        f"{cal.corners} corners, reprojection {cal.reprojection_px:.2f} px RMS, depth about the board's plane "
        f"{cal.depth_residual * 1e3:.2f} mm RMS"
    ]
    if truth is not None:
        mm, deg = pose_error(cal.X_TC, truth)
        doc["truth_error_mm"], doc["truth_error_deg"] = mm * 1e3, deg
        lines.append(f"simulation: {mm * 1e3:.2f} mm and {deg:.3f} deg from the rendering camera's true pose")
    return doc, lines


def cmd_board(args) -> None:
    from mog_drake.hardware.calibration import BOARD, write_board

    path = write_board(args.output)
    emit(args, {"output": path, "board": BOARD.text()}, f"wrote {path}: {BOARD.text()}")


def cmd_camera(args) -> None:
    _, cal, truth = _solve(args)
    doc, lines = _figures(cal, truth)
    doc["yaml"] = cal.yaml()
    emit(args, doc, cal.yaml() + "\n".join("# " + ln for ln in lines))


def cmd_check(args) -> None:
    from mog_drake.camera import camera_pose
    from mog_drake.hardware.calibration import pose_error

    sc, cal, truth = _solve(args)
    mm, deg = pose_error(camera_pose(sc.camera), cal.X_TC)
    doc, lines = _figures(cal, truth)
    doc["scenario_off_mm"], doc["scenario_off_deg"] = mm * 1e3, deg
    emit(
        args,
        doc,
        f"the scenario's camera.X_PB is {mm * 1e3:.2f} mm and {deg:.3f} deg off\n" + "\n".join(lines),
    )
