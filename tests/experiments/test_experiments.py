import json
import math
import time

import pytest

from mog_drake.errors import MogError
from mog_drake.experiments import conditions, picking_compare, picking_eval, planning_eval
from mog_drake.experiments.stats import mean_ci, proportion_ci
from mog_drake.experiments.sweep import check_params, load_results, run_sweep


def test_sweep_resumes_without_redoing_finished_tasks(tmp_path):
    calls = []

    def worker(task):
        calls.append(task["key"])
        return {"key": task["key"], "value": task["n"] ** 2}

    tasks = [{"key": f"t{i}", "n": i} for i in range(3)]
    run_sweep(tasks, worker, tmp_path, progress=False)
    more = tasks + [{"key": "t3", "n": 3}]
    out = run_sweep(more, worker, tmp_path, progress=False)
    assert calls == ["t0", "t1", "t2", "t3"]  # t0..t2 were not redone
    assert [r["value"] for r in out] == [0, 1, 4, 9]


def _worker_failing_on_t1(task):
    if task["key"] == "t1":
        raise ValueError("bad table")
    return {"key": task["key"], "value": task["n"]}


def _worker_ok(task):
    return {"key": task["key"], "value": task["n"]}


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_failing_task_does_not_stop_the_others_and_is_retried(tmp_path, jobs):
    tasks = [{"key": f"t{i}", "n": i} for i in range(4)]
    with pytest.raises(MogError, match=r"1 of 4 sweep tasks failed \(first: t1: ValueError: bad table\)"):
        run_sweep(tasks, _worker_failing_on_t1, tmp_path, jobs=jobs, progress=False)
    assert set(load_results(tmp_path / "results.jsonl")) == {"t0", "t2", "t3"}
    (failure,) = [json.loads(line) for line in (tmp_path / "failures.jsonl").read_text().splitlines()]
    assert failure["key"] == "t1" and "raise ValueError" in failure["traceback"]
    out = run_sweep(tasks, _worker_ok, tmp_path, jobs=jobs, progress=False)  # retries t1 only
    assert [r["value"] for r in out] == [0, 1, 2, 3]
    assert len((tmp_path / "results.jsonl").read_text().splitlines()) == 4


def test_torn_last_line_is_dropped(tmp_path):
    path = tmp_path / "results.jsonl"
    path.write_text(json.dumps({"key": "a", "v": 1}) + "\n" + '{"key": "b", "v"')
    assert set(load_results(path)) == {"a"}
    assert path.read_text().endswith("\n")


def test_a_folder_of_another_sweep_is_refused(tmp_path):
    check_params(tmp_path, {"experiment": "conditions", "seed": 0, "scenes_per_class": 2})
    check_params(tmp_path, {"experiment": "conditions", "seed": 0, "scenes_per_class": 5})  # growing is fine
    with pytest.raises(MogError, match="seed=0"):
        check_params(tmp_path, {"experiment": "conditions", "seed": 1, "scenes_per_class": 5})


def test_stats():
    m, h = mean_ci([1.0, 2.0, 3.0])
    assert m == 2.0 and h == pytest.approx(4.303 * 1.0 / 3**0.5, rel=1e-4)
    p, lo, hi = proportion_ci(8, 10)
    assert p == 0.8 and lo < 0.8 < hi


def test_tiny_conditions_sweep_end_to_end(tmp_path):
    summary, results = conditions.run(
        [2], 1, seed=3, out_dir=tmp_path, progress=False, n_positions=4, n_orientations=2
    )
    assert len(results) == 1 and results[0]["n_candidates"] == len(results[0]["candidates"]) > 0
    row = summary["rows"][0]
    for k in (
        "negatives",
        "positives",
        "tn_area_pct",
        "tn_diameter_pct",
        "tn_either_pct",
        "tn_both_pct",
        "false_negatives",
        "candidates_per_scene",
    ):
        assert k in row
    assert row["negatives"] + row["positives"] + row["physics_errors"] == results[0]["n_candidates"]
    assert summary["rows"][-1]["class"] == "all"
    # Resuming an identical sweep recomputes nothing and gives the same summary.
    again, _ = conditions.run(
        [2], 1, seed=3, out_dir=tmp_path, progress=False, n_positions=4, n_orientations=2
    )
    assert json.dumps(again, sort_keys=True) == json.dumps(summary, sort_keys=True)


def test_false_negatives_are_listed_with_a_replay():
    fake = [
        {
            "class": 2,
            "scene_seed": 2020001,
            "n_candidates": 2,
            "candidates": [
                [
                    0.0,
                    0.0,
                    0.0,
                    False,
                    True,
                    True,
                    "",
                ],  # rejected by the diameter condition, lifted: false negative
                [0.01, 0.0, 0.0, True, False, False, ""],  # rejected by area, failed: true negative
            ],
        }
    ]
    s = conditions.summarize(fake)
    assert s["rows"][0]["false_negatives"] == 1 and s["rows"][0]["tn_area_pct"] == 100.0
    fn = s["false_negatives"][0]
    assert fn["scene_seed"] == 2020001 and "--seed 2020001" in fn["replay"] and "--simulate" in fn["replay"]


def test_tiny_planner_sweep_end_to_end(tmp_path):
    summary, results = planning_eval.run(
        [2],
        1,
        seed=4,
        out_dir=tmp_path,
        methods=["gp", "rand-fil-phys"],
        progress=False,
        n_positions=4,
        n_orientations=2,
    )
    rows = {r["method"]: r for r in summary["rows"] if r["class"] == "2"}
    assert set(rows) == {"gp", "rand-fil-phys"}
    for r in rows.values():
        for k in ("time_s", "time_ci", "tested", "tested_ci", "found_pct", "gp_speedup"):
            assert k in r
    assert rows["gp"]["gp_speedup"] == pytest.approx(1.0)


def test_scene_memo_simulates_each_candidate_once_and_charges_its_time():
    from mog_drake.planning.protocol import GraspResult

    class Slow:
        """A verifier whose every real check 'takes' 2 s, the first one 5 s more to build."""

        last_build_time = 5.0

        def __init__(self):
            self.runs = 0

        def check(self, scene, group, grasp):
            self.runs += 1
            built = self.runs == 1
            return GraspResult(bool(grasp[0] > 0), wall_time=2.0 + (5.0 if built else 0.0), built=built)

    memo = planning_eval.SceneMemo(Slow())
    memo.start_method()
    a = memo.check(None, [0, 1], [1.0, 0.0, 0.0])
    memo.check(None, [0, 1], [-1.0, 0.0, 0.0])
    assert a.success and memo.charged == 0.0 and memo.replayed == 0 and memo.verifier.runs == 2

    memo.start_method()  # a second method: one replay, one new check, plus its own build
    b = memo.check(None, [0, 1], [1.0, 0.0, 0.0])
    assert b is a and memo.replayed == 1 and memo.charged == pytest.approx(2.0 + 5.0)
    memo.check(None, [0, 1], [2.0, 0.0, 0.0])
    assert memo.verifier.runs == 3 and memo.replayed == 1 and memo.charged == pytest.approx(7.0)

    memo.start_method()  # a method whose first check is new still pays a build
    memo.check(None, [0, 1], [3.0, 0.0, 0.0])
    assert memo.charged == pytest.approx(5.0)


def test_a_false_negative_is_replayed_and_explained():
    """Class 2, scene 20006: a candidate the diameter condition rejects that physics lifts.
    Replayed from the exact candidate, the jaws stop below h_fmin: a friction grasp."""
    fn = {
        "class": 2,
        "scene_seed": 20006,
        "grasp": [0.0024381, -0.0084481, 1.7951958],  # as recorded (rounded)
        "diameter_ok": False,
        "area_ok": True,
        "n_positions": 70,
        "n_orientations": 7,
    }
    (out,) = conditions.explain_false_negatives([fn])
    assert out["replayed_success"]
    assert out["h0_mm"] < out["h_fmin_mm"] and out["final_opening_mm"] < out["h_fmin_mm"]
    assert out["explanation"].startswith("held by friction")


def test_a_physics_fault_is_neither_negative_nor_positive():
    fake = [
        {
            "class": 3,
            "scene_seed": 1,
            "n_candidates": 3,
            "candidates": [
                [0.0, 0.0, 0.0, True, True, False, "CPU budget of 10 s exceeded at t = 0.3 s"],
                [0.0, 0.0, 0.5, False, True, False, "object 2 left the table (at [0.6, 0.0, 0.0])"],
                [0.0, 0.0, 1.0, True, True, True, ""],
            ],
        }
    ]
    row = conditions.summarize(fake)["rows"][0]
    assert (row["negatives"], row["positives"], row["physics_errors"], row["ejected"]) == (1, 1, 1, 1)
    assert row["tn_diameter_pct"] == 100.0


def test_summary_only_runs_nothing(tmp_path):
    from mog_drake.experiments.sweep import summary_only

    with summary_only():
        summary, results = conditions.run(
            [2], 1, seed=3, out_dir=tmp_path, progress=False, n_positions=4, n_orientations=2
        )
    assert results == [] and not (tmp_path / "results.jsonl").exists()


def test_summary_only_leaves_a_line_being_written_alone(tmp_path):
    """A summary printed while the sweep runs in another process may read a line the sweep is
    still writing: it leaves that line out of the summary and the file as it is."""
    from mog_drake.experiments.sweep import summary_only

    path = tmp_path / "results.jsonl"
    torn = json.dumps({"key": "t0", "value": 0}) + "\n" + '{"key": "t1", "val'
    path.write_text(torn)
    tasks = [{"key": f"t{i}", "n": i} for i in range(2)]
    with summary_only():
        out = run_sweep(tasks, _worker_ok, tmp_path, progress=False)
    assert [r["key"] for r in out] == ["t0"] and path.read_text() == torn
    out = run_sweep(tasks, _worker_ok, tmp_path, progress=False)  # the sweep itself repairs it
    assert [r["value"] for r in out] == [0, 1]
    assert [json.loads(line)["key"] for line in path.read_text().splitlines()] == ["t0", "t1"]


def _picking_record(scene, mode, success, pph, attempts=(), seed=None, timing=None):
    summary = {k: 1.0 for k in picking_compare.PAIRED}
    summary.update(success_rate=success, pph=pph, **(timing or {}))
    return {
        "key": f"s{scene}-{mode}",
        "scene": scene,
        "mode": mode,
        "scene_seed": scene if seed is None else seed,
        "summary": summary,
        "attempts": list(attempts),
    }


def test_two_picking_sweeps_are_compared_table_by_table():
    held = {"carried": [3, 4], "picked": 2}
    dropped_one = {"carried": [3, 4], "picked": 1}
    missed = {"carried": [], "picked": 0}
    a = [
        _picking_record(0, "mog", 0.90, 400.0, [held, dropped_one]),
        _picking_record(1, "mog", 0.80, 500.0, [missed]),
        _picking_record(2, "mog", 0.10, 100.0),  # B did not run this table
        _picking_record(3, "mog", 0.10, 100.0),  # B ran another table under this key
    ]
    b = [
        _picking_record(0, "mog", 1.00, 430.0, [held]),
        _picking_record(1, "mog", 0.90, 510.0, [held, {"carried": [5, 6, 7], "picked": 0}]),
        _picking_record(3, "mog", 1.00, 900.0, seed=99),
    ]
    doc = picking_compare.compare(a, b)
    assert doc["tables"] == 2
    rows = {r["metric"]: r for r in doc["rows"]}
    success = rows["success_rate"]
    assert success["tables"] == 2
    assert success["a"] == pytest.approx(85.0) and success["b"] == pytest.approx(95.0)
    assert success["b_minus_a"] == pytest.approx(10.0) and success["ci"] == pytest.approx(0.0)
    # Differences 30 and 10: mean 20, 95 % t half-width 12.706 * sd / sqrt(2) = 12.706 * 10.
    assert rows["pph"]["b_minus_a"] == pytest.approx(20.0) and rows["pph"]["ci"] == pytest.approx(
        127.06, rel=1e-4
    )
    drops = doc["transit_drops"]["mog"]
    # A's failed attempt lifted nothing (missed); B's lifted three and dropped them all (lost).
    assert drops["a"] == {"drop_attempts": 1, "dropped": 1, "attempts": 3, "missed": 1, "lost": 0}
    assert drops["b"] == {"drop_attempts": 1, "dropped": 3, "attempts": 3, "missed": 0, "lost": 1}
    assert "A 1 (1 of 3 attempts); B 3 (1 of 3 attempts)" in picking_compare.compare_text(doc)
    with pytest.raises(MogError, match="share no table"):
        picking_compare.compare(a[2:3], b)


def test_runs_record_their_machine_and_sweeps_from_machines_of_other_speeds_are_flagged():
    """Each run records its machine with the CPU time of a reference physics check; with
    latency.mode cpu the waits scale with it, so a pairing of runs whose reference checks
    differ by more than SPEED_TOLERANCE, or of runs that recorded none, says so; runs on one
    machine pair silently."""
    from mog_drake.experiments.machine import SPEED_TOLERANCE, machine, speed_gap

    here = machine()
    assert here["cores"] >= 1 and here["cpu"] and 0 < here["check_cpu_s"] < 30

    def runs(*speeds):
        return [
            {**_picking_record(k, "mog", 0.9, 500.0), **({"machine": {"check_cpu_s": s}} if s else {})}
            for k, s in enumerate(speeds)
        ]

    assert speed_gap(runs(0.30, 0.32), runs(0.31, 0.29)) == ""
    slower = speed_gap(runs(0.30, 0.32), runs(0.30 * SPEED_TOLERANCE * 1.1, 1.0))
    assert "machines differ" in slower and "0.30-0.32 s of CPU in A and 0.41-1.00 s in B" in slower
    assert speed_gap(runs(0.30, None), runs(0.30, 0.30)).startswith("A: some runs do not record")
    assert picking_compare.compare(runs(0.3, 0.3), runs(0.9, 0.9))["machines"]


def test_compare_refuses_a_sweep_of_other_tables_before_anything_runs(tmp_path, capsys):
    """A 3-object sweep compared with a 2-object one: one line naming the difference, exit 2,
    and the new sweep's folder not even made. Sweeps of the same tables with other settings
    (what --compare is for) are accepted."""
    from mog_drake.cli import main

    a = tmp_path / "a"
    a.mkdir()
    params = {
        "experiment": "picking",
        "seed": 0,
        "modes": ["mog"],
        "objects": 3,
        "time_limit": 60.0,
        "scenes": 1,
    }
    (a / "sweep.json").write_text(json.dumps(params))
    out = tmp_path / "b"
    code = main(
        [
            "eval",
            "picking",
            "--scenes",
            "1",
            "--modes",
            "mog",
            "--objects",
            "2",
            "--time-limit",
            "60",
            "--out",
            str(out),
            "--compare",
            str(a),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "ran other tables (objects 3, here 2)" in err, err
    assert not out.exists()
    with pytest.raises(MogError, match="seed 0, here 1"):
        picking_compare.check_comparable(a, {**params, "seed": 1})
    with pytest.raises(MogError, match="table"):
        picking_compare.check_comparable(a, {**params, "scenario": "table: [-0.2, 0.2, -0.3, 0.3]\n"})
    picking_compare.check_comparable(
        a, {**params, "scenario": "planner: {lookahead: {enabled: false}}\n", "scenes": 5}
    )
    (a / "sweep.json").write_text(json.dumps({**params, "experiment": "conditions"}))
    with pytest.raises(MogError, match="not a picking sweep"):
        picking_compare.check_comparable(a, params)
    (a / "sweep.json").write_text("[]")
    with pytest.raises(MogError, match="--compare: .* not a sweep's parameters"):
        picking_compare.check_comparable(a, params)


def test_push_mog_is_paired_with_sog_table_by_table_within_one_sweep():
    timed = {"robot_time_s": 80.0, "cycle_time_s": 100.0, "wait_planning_s": 15.0, "wait_perception_s": 5.0}
    sog_timed = {
        "robot_time_s": 100.0,
        "cycle_time_s": 100.0,
        "wait_planning_s": 0.0,
        "wait_perception_s": 0.0,
    }
    results = [
        _picking_record(0, "sog", 1.0, 500.0, timing=sog_timed),
        _picking_record(0, "push-mog", 1.0, 800.0, timing=timed),
        _picking_record(1, "sog", 1.0, 400.0),
        _picking_record(1, "push-mog", 0.9, 700.0),
        _picking_record(2, "sog", 1.0, 450.0),  # push-mog has not run table 2 yet
        _picking_record(0, "mog", 1.0, 999.0),
    ]
    doc = picking_compare.compare_modes(results, "sog", "push-mog")
    assert doc["tables"] == 2
    assert [t["table"] for t in doc["per_table"]] == [0, 1]
    assert [t["pph_ratio"] for t in doc["per_table"]] == pytest.approx([1.6, 1.75])
    # Had neither arm waited: table 0's push-mog waited 20 s of its 80 s of robot time (cycle
    # 100 s), sog 0 s of 100: 800 * 100 / 80 = 1000 PPH against 500, a ratio of 2.0.
    assert doc["per_table"][0]["wait_pct_push-mog"] == pytest.approx(25.0)
    assert doc["per_table"][0]["robot_pph_ratio"] == pytest.approx(2.0)
    assert doc["per_table"][1]["robot_pph_ratio"] == pytest.approx(1.75)  # cycle = robot time
    pph = next(r for r in doc["rows"] if r["metric"] == "pph")
    assert pph["mode"] == "push-mog vs sog" and pph["b_minus_a"] == pytest.approx(300.0)
    assert pph["a"] == pytest.approx(450.0) and pph["b"] == pytest.approx(750.0)


def test_push_mog_robot_time_is_split_into_grasps_and_pushes_against_sog():
    def run(scene, mode, robot, attempts, push_time=0.0, pushes=0):
        r = _picking_record(scene, mode, 1.0, 500.0, timing={"robot_time_s": robot, "push_time_s": push_time})
        r["summary"]["attempts"] = attempts
        r["pushes"] = [{"push": {"distance": 0.03}} for _ in range(pushes)]
        return r

    results = [
        run(0, "sog", 100.0, 20),
        run(0, "push-mog", 80.0, 12, push_time=20.0, pushes=4),
        run(1, "sog", 90.0, 18),
        run(1, "push-mog", 60.0, 12),
        run(2, "sog", 90.0, 18),  # push-mog has not run table 2 yet
    ]
    split = picking_compare.compare_modes(results, "sog", "push-mog")["robot_time"]
    assert split["tables"] == 2
    assert split["ratio"] == pytest.approx((100 / 80 + 90 / 60) / 2)
    assert split["ratio_pushes_free"] == pytest.approx((100 / 60 + 90 / 60) / 2)
    assert split["grasp_s_a"] == pytest.approx(190 / 38) and split["grasp_s_b"] == pytest.approx(120 / 24)
    assert (
        split["pushes"] == 4
        and split["push_s"] == pytest.approx(5.0)
        and split["push_mm"] == pytest.approx(30.0)
    )
    text = picking_compare.robot_time_text(split, "sog", "push-mog")
    assert "1.38x" in text and "1.58x" in text and "a push 5.00 s (4 pushes" in text
    assert picking_compare.robot_time_split([], []) == {}


def test_grouping_ceiling_counts_the_grasps_alg1_needs_if_every_group_lifts_whole():
    from conftest import make_scene

    from mog_drake.experiments.picking_eval import grouping_ceiling

    # Three bars in a row 30 mm apart: the middle one's neighbourhood holds all three (one
    # grasp), the ends' hold two each (subsets, dropped). A fourth bar lies alone.
    row = [("thin_bar", 0.03 * k, 0.0, 1.5708) for k in range(3)]
    alone = ("thin_bar", -0.15, 0.1, 0.0)
    assert grouping_ceiling(make_scene([*row, alone]), 0.035, 0.075) == pytest.approx(4 / 2)
    # A radius under the spacing leaves four singles. A stroke too short for three bars'
    # widths (3 x 7 mm): RankObjGroups drops the triple, and CreateObjGroups already dropped
    # the pairs inside it, so one bar goes alone; the other two are then a pair.
    assert grouping_ceiling(make_scene([*row, alone]), 0.025, 0.075) == pytest.approx(1.0)
    assert grouping_ceiling(make_scene([*row, alone]), 0.035, 0.018) == pytest.approx(4 / 3)
    assert grouping_ceiling(make_scene([*row, alone]), 0.035, 0.022) == pytest.approx(2.0)
    assert math.isnan(grouping_ceiling(make_scene([]), 0.035, 0.075))
    # Grouped by the conditions, one grasp closes on the whole row, wherever its bars lie
    # within the stroke: 20 mm apart four bars are one group (two grasps with the lone one),
    # where the 35 mm radius needs three.
    row4 = [("thin_bar", 0.02 * k, 0.0, 1.5708) for k in range(4)]
    assert grouping_ceiling(make_scene([*row4, alone]), 0.035, 0.075) == pytest.approx(5 / 3)
    assert grouping_ceiling(make_scene([*row4, alone]), 0.035, 0.075, "conditions") == pytest.approx(5 / 2)


def test_the_arms_wait_is_summarised_as_its_median_share_of_robot_time():
    """wait_share_pct: per mode, the median over tables of (waits for perception and
    planning) / robot time, in percent; tables without waits (older sweeps) are left out."""
    records = []
    for scene, (wait_p, wait_q, robot) in enumerate(
        [(0.5, 9.5, 100.0), (0.0, 30.0, 150.0), (1.0, 1.0, 200.0)]
    ):
        r = _picking_record(scene, "mog", 1.0, 600.0)
        r["summary"].update(wait_perception_s=wait_p, wait_planning_s=wait_q, robot_time_s=robot)
        records.append(r)
    old = _picking_record(3, "mog", 1.0, 500.0)
    for key in ("wait_perception_s", "wait_planning_s"):
        old["summary"].pop(key, None)
    row = picking_eval.summarize(records + [old], ["mog"])["rows"][0]
    assert row["scenes"] == 4
    assert row["wait_share_pct"] == pytest.approx(10.0)  # shares 10, 20 and 1 %


def test_picks_per_hour_are_also_given_at_the_paper_s_robot_cycle():
    """pph_paper_cycle: per table, the objects each attempt took on the paper's 12.2 s cycle;
    the mean over tables: 33 objects in 22 and in 33 attempts, and 30 of 33 (picked 90.9 %) in 30."""
    records = []
    for scene, (picked, attempts) in enumerate([(100.0, 22), (100.0, 33), (100 * 30 / 33, 30)]):
        r = _picking_record(scene, "mog", 1.0, 600.0)
        r["summary"].update(objects=33, picked_pct=picked, attempts=attempts)
        records.append(r)
    row = picking_eval.summarize(records, ["mog"])["rows"][0]
    assert row["pph_paper_cycle"] == pytest.approx((1.5 + 1.0 + 1.0) / 3 * 3600 / 12.2)


def test_a_push_costs_the_paper_s_cycle_its_share_of_a_grasp_s_robot_time():
    """push-mog: 33 objects in 20 attempts of 5 s of robot time and 6 pushes of 3.5 s (21 s):
    20 + 21 / 5 = 24.2 of the paper's cycles, not 20."""
    r = _picking_record(0, "push-mog", 1.0, 600.0)
    r["summary"].update(objects=33, picked_pct=100.0, attempts=20, robot_time_s=121.0, push_time_s=21.0)
    row = picking_eval.summarize([r], ["push-mog"])["rows"][0]
    assert row["pph_paper_cycle"] == pytest.approx(33 / 24.2 * 3600 / 12.2)


def test_the_arms_wait_is_split_by_what_the_decision_had_from_the_lookahead():
    """Each idle gap before an attempt or a push (from the end of the one before) goes to its
    decision's kind: the table's first, then by its lookahead. The grasp a push set up waits
    for nothing: its gap is the jaws opening (robot time)."""
    run = {
        "mode": "mog",
        "summary": {"robot_time_s": 20.0},
        "attempts": [
            {"start": 2.0, "end": 8.0, "lookahead": ""},
            {"start": 9.0, "end": 15.0, "lookahead": "used"},
            {"start": 18.0, "end": 24.0, "lookahead": "merged"},
            {"start": 24.4, "end": 30.0, "after_push": True},
        ],
        "pushes": [{"start": 15.5, "end": 17.0, "lookahead": "dropped"}],
    }
    w = picking_eval.wait_by_decision([run])
    assert (w["first"], w["used"], w["dropped"], w["merged"], w[""]) == (2.0, 1.0, 0.5, 1.0, 0.0)
    assert w["robot_time_s"] == 20.0
    text = picking_eval.wait_text([run], ["mog"])
    assert "the arm waited 4 s (22.5 % of robot time)" in text


def test_the_cell_bench_times_each_systems_callbacks_apart():
    """`bench station`'s split: a system whose update evaluates another system's output is
    charged its own CPU, not the other's (each burns a known amount of CPU)."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder, LeafSystem

    from mog_drake.experiments.bench.cell import _Timers

    def burn(seconds):
        end = time.thread_time() + seconds
        while time.thread_time() < end:
            pass

    class Source(LeafSystem):
        def __init__(self):
            super().__init__()
            self.DeclareVectorOutputPort("y", 1, self._calc)

        def _calc(self, context, output):
            burn(0.02)
            output.SetFromVector([1.0])

    class Reader(LeafSystem):
        def __init__(self):
            super().__init__()
            self._u = self.DeclareVectorInputPort("u", 1)
            self.DeclarePeriodicPublishEvent(0.1, 0.0, self._read)

        def _read(self, context):
            burn(0.01)
            self._u.Eval(context)

    timers = _Timers()
    with timers.installed():
        builder = DiagramBuilder()
        src, reader = builder.AddSystem(Source()), builder.AddSystem(Reader())
    builder.Connect(src.get_output_port(), reader.get_input_port())
    Simulator(builder.Build()).AdvanceTo(0.45)  # 5 publishes
    assert timers.total["Source"] == pytest.approx(0.10, rel=0.3)
    assert timers.total["Reader"] == pytest.approx(0.05, rel=0.3)


def test_push_mog_lone_grasps_are_counted_by_reason_only_where_recorded():
    from mog_drake.experiments.picking_compare import lone_reasons

    run = _picking_record(
        0, "push-mog", 1.0, 800.0, [{"lone": "too far"}, {"lone": "too far"}, {}, {"lone": "blocked"}]
    )
    run["summary"]["lone_grasps"] = 3
    assert lone_reasons([run]) == {"too far": 2, "blocked": 1, "not worth it": 0, "out of pushes": 0}
    old = _picking_record(1, "push-mog", 1.0, 800.0, [{}])  # a run from before: nothing recorded
    assert lone_reasons([old]) == {} and lone_reasons([_picking_record(0, "mog", 1.0, 800.0)]) == {}


def test_the_picking_figure_draws_the_papers_bars_only_where_it_reports_the_mode(tmp_path, monkeypatch):
    """Beside mog and sog, the paper's Table 1 bars; a push-mog sweep alone gets its own bars,
    centred, and no legend entry for bars that are not there."""
    from mog_drake.experiments import figures
    from mog_drake.experiments.picking_eval import PAPER_TABLE1

    saved = []
    monkeypatch.setattr(figures, "_save", lambda fig, path: saved.append(fig) or path)
    row = {k: 90.0 for k in ("success_rate", "picked_pct", "pph")} | {
        k + "_ci": 1.0 for k in ("success_rate", "picked_pct", "pph")
    }
    for modes, bars, labels in ((("mog", "sog"), 4, 2), (("push-mog",), 1, 1)):
        figures.picking_figure({"rows": [row | {"mode": m} for m in modes]}, tmp_path / "p.png", PAPER_TABLE1)
        ax, legend_ax = saved[-1].axes[0], saved[-1].axes[-1]
        assert len(ax.patches) == bars and len(legend_ax.get_legend().get_texts()) == labels
        centres = sorted(p.get_x() + p.get_width() / 2 for p in ax.patches)
        assert (centres[0] == 0.0) == (len(modes) == 1)
