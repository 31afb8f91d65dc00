"""Sweeps as DataFrames (`experiments.frames`): where the open plates came down."""

import json

import pytest

pytest.importorskip("pandas")


def _attempt(picked, jaws_on, force):
    return {
        "start": 0.0,
        "end": 5.0,
        "group": [0],
        "picked": picked,
        "carried": [0] * picked,
        "held_width": 0.03,
        "jaws_on": jaws_on,
        "approach_force": force,
    }


def test_landings_count_the_attempts_whose_plates_came_down_on_an_object(tmp_path):
    from mog_drake.experiments import frames

    run = {
        "key": "s0-mog",
        "scene": 0,
        "mode": "mog",
        "attempts": [
            _attempt(1, {}, 0.0),  # clear, taken
            _attempt(1, {"3": 4.0}, 60.0),  # landed 4 mm on object 3, taken all the same
            _attempt(0, {"5": 9.5}, 180.0),  # landed 9.5 mm, pressed past the stop, failed
            _attempt(1, {"2": 0.4}, 2.0),  # brushed 0.4 mm: not a landing
        ],
    }
    old = {**run, "key": "s1-mog", "scene": 1, "attempts": [{"start": 0.0, "group": [0], "picked": 1}]}
    (tmp_path / "results.jsonl").write_text(json.dumps(run) + "\n" + json.dumps(old) + "\n")
    (row,) = frames.landings({"here": tmp_path}).to_dict("records")
    assert row["attempts"] == 4  # the run from before landings were recorded is left out
    assert row["landed_pct"] == 50.0 and row["success_if_landed_pct"] == 50.0
    assert row["success_pct"] == 75.0 and row["success_if_landings_fail_pct"] == 50.0
    assert row["pressed_to_stop_pct"] == 25.0


def test_an_attempt_stopped_on_the_way_down_is_its_own_outcome():
    from mog_drake.experiments import frames

    stopped = {"group": [0], "picked": 0, "carried": [], "held_width": None, "stopped": {"force": 52.0}}
    assert frames.outcome(stopped) == "stopped on the way down"
    assert frames.outcome({**stopped, "stopped": None}) == "closed on nothing"


def _run(scene, mode, success):
    attempts = [{"start": 0.0, "group": [0], "picked": 1}]
    summary = {
        "objects": 1,
        "attempts": 1,
        "success_rate": success,
        "picked_pct": 100.0,
        "objects_per_success": 1.0,
        "pph": 100.0,
    }
    return {"key": f"s{scene}-{mode}", "scene": scene, "mode": mode, "summary": summary, "attempts": attempts}


def test_the_study_compares_levels_on_the_tables_each_mode_ran_at_every_level(tmp_path):
    from mog_drake.experiments import frames

    # Level 1 ran mog on tables 0-2 and sog on 0; level 2 mog on 0-1 and sog on 0-1.
    ladder = {1: [(0, "mog", 1.0), (1, "mog", 1.0), (2, "mog", 0.0), (0, "sog", 0.5)],
              2: [(0, "mog", 0.5), (1, "mog", 0.5), (0, "sog", 0.25), (1, "sog", 0.0)]}  # fmt: skip
    folders = {}
    for level, runs in ladder.items():
        folders[level] = tmp_path / f"level{level}"
        folders[level].mkdir()
        (folders[level] / "results.jsonl").write_text("".join(json.dumps(_run(*r)) + "\n" for r in runs))
    rows = {(r["level"], r["mode"]): r for r in frames.study(folders).to_dict("records")}
    assert rows[1, "mog"]["scenes"] == 2 and rows[1, "mog"]["success_rate"] == 100.0  # table 2 left out
    assert rows[2, "mog"]["success_rate"] == 50.0
    assert rows[1, "sog"]["scenes"] == rows[2, "sog"]["scenes"] == 1  # table 0 alone
    assert rows[2, "sog"]["success_rate"] == 25.0
    every = {(r["level"], r["mode"]): r for r in frames.study(folders, common=False).to_dict("records")}
    assert every[1, "mog"]["scenes"] == 3 and every[2, "sog"]["scenes"] == 2


def test_a_level_may_take_each_mode_from_its_own_sweep(tmp_path):
    """Every source at one level: mog from one sweep, sog from another that ran both modes
    (its mog runs are left out)."""
    from mog_drake.experiments import frames

    sweeps = {
        "a": [(0, "mog", 1.0), (1, "mog", 0.5), (0, "sog", 1.0)],
        "b": [(0, "sog", 0.5), (1, "sog", 0.0), (0, "mog", 0.0)],
    }
    for name, runs in sweeps.items():
        (tmp_path / name).mkdir()
        (tmp_path / name / "results.jsonl").write_text("".join(json.dumps(_run(*r)) + "\n" for r in runs))
    rows = frames.study({"every": {"mog": tmp_path / "a", "sog": tmp_path / "b"}}).to_dict("records")
    by_mode = {r["mode"]: r for r in rows}
    assert set(by_mode) == {"mog", "sog"} and by_mode["mog"]["scenes"] == by_mode["sog"]["scenes"] == 2
    assert by_mode["mog"]["success_rate"] == 75.0 and by_mode["sog"]["success_rate"] == 25.0
    att = frames.attempts({"mog": tmp_path / "a", "sog": tmp_path / "b"})
    assert sorted(zip(att["mode"], att.table)) == [("mog", 0), ("mog", 1), ("sog", 0), ("sog", 1)]
