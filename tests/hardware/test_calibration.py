"""`mog-drake calibrate`: the camera's pose from a printed ChArUco board, checked in
simulation (the station renders the board on an empty table)."""

from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("cv2")

from mog_drake.errors import MogError  # noqa: E402
from mog_drake.hardware.calibration import BOARD, BoardSpec, board_in_table, pose_error, solve  # noqa: E402
from mog_drake.scenario import ClutteredScene, load_scenario, scenario_from_text  # noqa: E402
from mog_drake.station.board import board_frame  # noqa: E402


def _realistic(seed: int, scale: float = 1.0):
    sc = load_scenario("realistic")
    real = replace(
        sc.realism,
        camera_offset=sc.realism.camera_offset * scale,
        camera_tilt_deg=sc.realism.camera_tilt_deg * scale,
    )
    return replace(sc, scene=ClutteredScene(seed=seed), realism=real)


@pytest.mark.parametrize("seed,scale", [(0, 1.0), (1, 1.0), (21, 10.0)])
def test_the_drawn_camera_error_is_recovered_to_a_millimetre(seed, scale):
    """The realistic cell's calibration error (1.5 mm and 0.1 deg per axis), and ten times it:
    the pose solved from the rendered board is within 1 mm and 0.1 deg of the rendering
    camera's, and the printed YAML is the scenario's camera.X_PB."""
    sc = _realistic(seed, scale)
    rgb, depth, intrinsics, truth = board_frame(sc)
    cal = solve(rgb, depth, intrinsics, board_in_table(0.0, 0.0, 0.0))
    before = pose_error(
        np.asarray(load_scenario("realistic").camera.X_PB.GetDeterministicValue().GetAsMatrix4()), truth
    )
    mm, deg = pose_error(cal.X_TC, truth)
    assert before[0] > 0.001 and mm < 0.001 and deg < 0.1
    assert cal.corners == BOARD.corners and cal.reprojection_px < 0.6
    from mog_drake.camera import camera_pose

    pasted = scenario_from_text(cal.yaml())
    assert np.allclose(camera_pose(pasted.camera), cal.X_TC, atol=2e-5)


def test_a_board_elsewhere_on_the_table_and_turned_gives_the_same_pose():
    sc = _realistic(2)
    at = (0.05, -0.04, np.radians(20.0))
    rgb, depth, intrinsics, truth = board_frame(sc, board_at=at)
    mm, deg = pose_error(solve(rgb, depth, intrinsics, board_in_table(*at)).X_TC, truth)
    assert mm < 0.001 and deg < 0.1


def test_bad_frames_are_refused_in_one_line():
    sc = _realistic(3)
    rgb, depth, intrinsics, _ = board_frame(sc)
    X_TB = board_in_table(0.0, 0.0, 0.0)
    with pytest.raises(MogError, match="no calibration board found"):  # an empty table
        solve(np.full_like(rgb, 200), depth, intrinsics, X_TB)
    half = board_frame(sc, board_at=(0.0, 0.36, 0.0))  # half of it past the image's edge
    with pytest.raises(MogError, match=r"only \d+ of the board's 24 corners are seen"):
        solve(half[0], half[1], intrinsics, board_in_table(0.0, 0.36, 0.0))
    import cv2

    blurred = cv2.GaussianBlur(rgb, (0, 0), 4.0)
    noisy = np.clip(blurred + np.random.default_rng(0).normal(0, 60, rgb.shape), 0, 255).astype(np.uint8)
    with pytest.raises(MogError, match="no calibration board found|corners are seen|the fit is poor"):
        solve(noisy, depth, intrinsics, X_TB)
    # A board of another size (40 mm squares believed, 38 mm printed) fits the image as well
    # as the right one and disagrees with the depth.
    wrong = BoardSpec(square=0.040, marker=0.0295)
    with pytest.raises(MogError, match="off a board of its size: is it printed at 100 %"):
        solve(rgb, depth, intrinsics, board_in_table(0.0, 0.0, 0.0, wrong), wrong)


def test_the_cli_prints_the_pose_checks_it_and_writes_the_board(tmp_path, capsys):
    from mog_drake.cli import main

    assert main(["calibrate", "camera", "--scenario", "realistic", "--seed", "4"]) == 0
    text = capsys.readouterr().out
    assert text.startswith("camera:\n  X_PB:") and "simulation:" in text
    scenario_from_text(text.split("#")[0])  # pastes into a scenario as it is
    # The check: the scenario's pose is off by the drawn error (the rendering camera is the
    # scenario's camera moved by it), and says so.
    assert main(["calibrate", "check", "--scenario", "realistic", "--seed", "4", "--json"]) == 0
    import json

    doc = json.loads(capsys.readouterr().out)
    sc = _realistic(4)
    truth = board_frame(sc)[3]
    from mog_drake.camera import camera_pose

    drawn = pose_error(camera_pose(sc.camera), truth)[0] * 1e3
    assert drawn > 1.0 and abs(doc["scenario_off_mm"] - drawn) < 2.0 and doc["truth_error_mm"] < 2.0
    for name in ("board.pdf", "board.png"):
        assert main(["calibrate", "board", "-o", str(tmp_path / name)]) == 0
        assert (tmp_path / name).stat().st_size > 10_000
    capsys.readouterr()
    code = main(["calibrate", "camera", "--scenario", "realistic", "--board-at", "0", "360", "0"])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("mog-drake: error: only") and err.count("\n") == 1
