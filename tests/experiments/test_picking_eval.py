"""eval picking: a tiny sweep, a sweep grown by a mode, the base scenario."""

import json

import pytest

from mog_drake.scenario import ClutteredScene


def test_tiny_picking_evaluation(tmp_path):
    from mog_drake.experiments import picking_eval

    summary, results = picking_eval.run(
        1, ["mog", "sog"], seed=2, out_dir=tmp_path, objects=3, time_limit=60.0, progress=False
    )
    assert {r["mode"] for r in summary["rows"]} == {"mog", "sog"}
    for r in summary["rows"]:
        for k in ("success_rate", "picked_pct", "pph", "objects_per_success", "success_rate_ci"):
            assert k in r
    assert summary["pph_ratio_mog_over_sog"] > 0
    assert len(results) == 2 and all(r["summary"]["objects"] == 3 for r in results)
    for r, res in zip(
        sorted(summary["rows"], key=lambda r: r["mode"]), sorted(results, key=lambda r: r["mode"])
    ):
        assert sum(r["finished"].values()) == r["scenes"] == 1 and res["summary"]["finished"] in r["finished"]
        left = r["left_in_view"] + r["left_out_of_view"] + r["left_off_table"]
        assert left == len(res["left"]) == round(3 * (1 - res["summary"]["picked_pct"] / 100))
    assert picking_eval.losses_text(summary).count("runs ended:") == 2
    mog = next(r for r in summary["rows"] if r["mode"] == "mog")
    # The seeded 3-object table's grouping ceiling, computed again by hand from its scene.
    (task,) = picking_eval.tasks(1, ["mog"], seed=2, objects=3, time_limit=60.0)
    assert mog["grouping_ceiling"] == picking_eval.task_grouping_ceiling(task) >= 1.0
    assert "grouping ceiling" in picking_eval.losses_text(summary)


def test_a_picking_sweep_grows_by_a_mode_without_rerunning_the_other(tmp_path, monkeypatch):
    from mog_drake.experiments import picking_eval
    from mog_drake.systems import pick
    from mog_drake.systems.pick_run import PickRun

    seen = []

    def fake_run(sc):
        seen.append(sc.planner.mode)
        return PickRun(objects=5, shapes=["cube"] * 5)

    monkeypatch.setattr(pick, "run_pick", fake_run)
    picking_eval.run(2, ["mog"], seed=4, out_dir=tmp_path, objects=5, progress=False)
    summary, results = picking_eval.run(
        2, ["mog", "sog"], seed=4, out_dir=tmp_path, objects=5, progress=False
    )
    assert seen == ["mog", "mog", "sog", "sog"]
    assert sorted(r["key"] for r in results) == ["s0-mog", "s0-sog", "s1-mog", "s1-sog"]
    assert [r["mode"] for r in summary["rows"]] == ["mog", "sog"]
    assert json.loads((tmp_path / "sweep.json").read_text())["modes"] == ["mog", "sog"]


def test_picking_evaluation_runs_a_base_scenario_and_refuses_to_mix_two(tmp_path, capsys, monkeypatch):
    from mog_drake.cli import main
    from mog_drake.errors import MogError
    from mog_drake.experiments import picking_eval
    from mog_drake.experiments.sweep import summary_only

    text = "planner:\n  loop:\n    group_radius: 0.045\nverifier:\n  hold_time: 1.5\nrobot:\n  max_joint_speed: 2.0\n"
    (task,) = picking_eval.tasks(1, ["sog"], seed=4, objects=5, time_limit=60.0, scenario=text)
    sc = picking_eval.task_scenario(task)
    assert (sc.planner.loop.group_radius, sc.verifier.hold_time, sc.robot.max_joint_speed) == (
        0.045,
        1.5,
        2.0,
    )
    assert (sc.planner.mode, sc.planner.seed, sc.scene.seed, sc.scene.n_objects) == (
        "sog",
        4_000_000,
        4_000_000,
        5,
    )
    assert (type(sc.scene), sc.time_limit) == (ClutteredScene, 60.0)
    (default_task,) = picking_eval.tasks(1, ["sog"], seed=4, objects=5, time_limit=60.0)
    assert (
        "scenario" not in default_task
        and picking_eval.task_scenario(default_task).planner.loop.group_radius == 0.035
    )

    from mog_drake.systems import pick
    from mog_drake.systems.pick_run import PickRun

    seen = []
    monkeypatch.setattr(
        pick, "run_pick", lambda sc: seen.append(sc) or PickRun(objects=5, shapes=["cube"] * 5)
    )
    record = picking_eval.picking_worker(task)
    assert seen[0].planner.loop.group_radius == 0.045 and record["summary"]["objects"] == 5
    assert record["scenario"] != text and len(record["scenario"]) == 16  # the text lives in sweep.json
    assert record["machine"]["check_cpu_s"] > 0  # what its waits scale with (latency.mode cpu)

    picking_eval.run(1, ["sog"], seed=4, out_dir=tmp_path, objects=5, progress=False, scenario=text)
    assert json.loads((tmp_path / "sweep.json").read_text())["scenario"] == text
    with pytest.raises(MogError, match="holds a sweep with scenario="):
        picking_eval.run(1, ["sog"], seed=4, out_dir=tmp_path, objects=5, progress=False)
    with summary_only(), pytest.raises(MogError, match="holds a sweep with scenario="):
        picking_eval.run(1, ["sog"], seed=4, out_dir=tmp_path, objects=5, progress=False)
    # A comment edited in the file after the sweep ran leaves the same scenario: it resumes and
    # summarises; a value changed does not.
    edited = "# written after the sweep ran\n" + text.replace("0.045\n", "0.045   # m\n")
    ran = len(seen)
    with summary_only():
        picking_eval.run(1, ["sog"], seed=4, out_dir=tmp_path, objects=5, progress=False, scenario=edited)
    picking_eval.run(1, ["sog"], seed=4, out_dir=tmp_path, objects=5, progress=False, scenario=edited)
    assert len(seen) == ran  # nothing ran again
    with pytest.raises(MogError, match="holds a sweep with scenario="):
        picking_eval.run(1, ["sog"], seed=4, out_dir=tmp_path, objects=5, progress=False,
                         scenario=edited.replace("0.045", "0.04"))  # fmt: skip
    bad = tmp_path / "bad.yaml"
    bad.write_text("planner:\n  loop:\n    group_radius: -1\n")
    assert main(["eval", "picking", "--scenario", str(bad), "--out", str(tmp_path / "x")]) == 2
    assert "group_radius must be in" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()  # refused before anything was written


def _attempt(picked: int, **recorded) -> dict:
    """One attempt's record as the pick loop stores it, with ``recorded`` fields added."""
    return {
        "start": 0.0,
        "end": 1.0,
        "group": [0],
        "picked": picked,
        "carried": [0] if picked else [],
        **recorded,
    }


def _run(attempts: list[dict]) -> dict:
    """One mog table's record holding ``attempts`` (the summary's numbers are not read here)."""
    summary = {"success_rate": 0.5, "picked_pct": 50.0, "pph": 100.0, "objects_per_success": 1.0}
    return {"mode": "mog", "scene_seed": 0, "summary": summary, "attempts": attempts}


def test_the_summary_counts_attempts_planned_blind_to_an_object_in_view():
    """Attempts whose scene had nothing for an object lying in view (`scoring.unseen`) are
    counted per mode, with how many of them failed, and named in the losses' lines."""
    from mog_drake.experiments import picking_eval

    run = _run([_attempt(1), _attempt(0, unseen=[3]), _attempt(1, unseen=[3, 4]), _attempt(1)])
    (row,) = picking_eval.summarize([run], ["mog"])["rows"]
    assert (row["unseen_attempts"], row["unseen_failed"]) == (2, 1)
    assert (
        "mog: 2 attempts planned on a scene that had nothing for an object lying in view, 1 of them failed"
        in (picking_eval.losses_text({"rows": [row]}))
    )
    run["attempts"] = [_attempt(1)]
    (row,) = picking_eval.summarize([run], ["mog"])["rows"]
    assert "unseen_attempts" not in row


def test_the_summary_splits_the_last_resort_s_grasps_from_the_others():
    """Attempts whose decision was a last resort (`PickDecision.last_resort`) are counted per
    mode apart from the others, each with how many took an object, and named in the losses'
    lines; sweeps with no last resort print nothing of it."""
    from mog_drake.experiments import picking_eval

    last = {"last_resort": True}
    run = _run([_attempt(1), _attempt(0, **last), _attempt(2, **last), _attempt(1), _attempt(0)])
    (row,) = picking_eval.summarize([run], ["mog"])["rows"]
    assert (row["last_resort"], row["first_pass"]) == ([1, 2], [2, 3])
    assert (
        "mog: the last resort's grasps took objects 1 of 2 times (50 %), the others 2 of 3 (67 %)"
        in picking_eval.losses_text({"rows": [row]})
    )
    run["attempts"] = [_attempt(1), _attempt(0)]
    (row,) = picking_eval.summarize([run], ["mog"])["rows"]
    assert "last_resort" not in row
    assert "last resort" not in picking_eval.losses_text({"rows": [row]})


def test_a_pairing_of_sweeps_from_machines_of_other_speeds_says_so(tmp_path, monkeypatch):
    """Two sweeps of the same tables, one of them re-recorded as run on a machine three times
    slower: the paired report ends its table with a warning; with fixed latency on both sides,
    where speed does not enter, it does not."""
    from mog_drake.experiments import picking_eval
    from mog_drake.experiments.sweep import summary_only
    from mog_drake.systems import pick
    from mog_drake.systems.pick_run import PickRun

    monkeypatch.setattr(pick, "run_pick", lambda sc: PickRun(objects=5, shapes=["cube"] * 5))
    for latency in ("cpu", "fixed"):
        a, b = tmp_path / f"a_{latency}", tmp_path / f"b_{latency}"
        text = f"latency:\n  mode: {latency}\n"
        for out in (a, b):
            picking_eval.run(1, ["mog"], seed=4, out_dir=out, objects=5, progress=False, scenario=text)
        rec = json.loads((a / "results.jsonl").read_text())
        rec["machine"]["check_cpu_s"] *= 3
        (a / "results.jsonl").write_text(json.dumps(rec) + "\n")
        summary, results = picking_eval.run(
            1, ["mog"], seed=4, out_dir=b, objects=5, progress=False, scenario=text
        )
        with summary_only():
            text_out = picking_eval.report(summary, results, b, compare_dir=str(a))
        assert ("warning: the runs' machines differ" in text_out) == (latency == "cpu")
