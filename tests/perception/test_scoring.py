"""Scoring perception against the truth (pose_errors)."""

import math

import pytest


def test_pose_errors_take_yaw_modulo_a_near_symmetry():
    from conftest import make_scene

    from mog_drake.perception import pose_errors, symmetry_order
    from mog_drake.scenes import default_library

    lib = default_library()
    assert symmetry_order(lib["pink_pentagon"].vertices) == 1  # regular within 0.5 mm only
    assert symmetry_order(lib["thin_bar"].vertices) == 2
    truth = make_scene([("pink_pentagon", 0.0, 0.0, 0.1), ("thin_bar", 0.1, 0.0, 0.2)])
    seen = make_scene(
        [("pink_pentagon", 0.0, 0.0, 0.1 + 2 * math.pi / 5 + 0.01), ("thin_bar", 0.1, 0.0, 0.2 + math.pi / 2)]
    )
    errs = pose_errors(seen, truth)
    assert errs[0]["yaw"] == pytest.approx(0.01, abs=1e-9)  # the same footprint, turned 0.01 rad
    assert errs[1]["yaw"] == pytest.approx(math.pi / 2)  # a bar across its true axis is wrong
