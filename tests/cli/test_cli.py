import json
import subprocess
import sys

import pytest

from mog_drake.cli import main


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_shapes_json_lists_the_library(capsys):
    code, out, _ = run(capsys, "shapes", "--json")
    assert code == 0
    doc = json.loads(out)
    shapes = {s["name"]: s for s in doc["shapes"]}
    assert len(shapes) == 14
    bar = shapes["thin_bar"]
    assert bar["sides"] == 4 and bar["d_fmin"] == pytest.approx(0.007)
    assert bar["final_diameters"] == pytest.approx([0.007, 0.05])
    assert bar["vertices"][0] == pytest.approx([-0.025, -0.0035])  # CCW from the lowest-left corner


def test_generate_check_candidates(tmp_path, capsys):
    scene = tmp_path / "row.yaml"
    code, _, _ = run(
        capsys, "scene", "generate", "--kind", "row", "--class", "3", "--seed", "1", "-o", str(scene)
    )
    assert code == 0 and scene.exists()
    code, out, _ = run(capsys, "check", str(scene), "--grasp", "0", "0", "0", "--json")
    doc = json.loads(out)
    assert code == 0
    for k in ("h0", "h_fmin", "areas", "diameter_ok", "area_ok", "collision_free"):
        assert k in doc
    assert set(doc["areas"]) == {"0", "1", "2"}
    code, out, _ = run(capsys, "candidates", str(scene), "--json")
    doc = json.loads(out)
    areas = [c["area_total"] for c in doc["candidates"]]
    assert areas == sorted(areas, reverse=True)
    assert sum(doc["counts"].values()) == len(doc["candidates"]) > 0
    png = tmp_path / "row.png"
    code, _, _ = run(capsys, "scene", "show", str(scene), "--candidates", "-o", str(png))
    assert code == 0 and png.stat().st_size > 10_000


@pytest.mark.parametrize(
    "argv,msg",
    [
        (["check", "missing.yaml", "--grasp", "0", "0", "0"], "file not found"),
        (["scene", "generate", "--kind", "row"], "needs --class"),
        (["scene", "generate", "--kind", "row", "--class", "9"], "row class must be one of"),
    ],
)
def test_user_errors_are_one_line_exit_2(capsys, argv, msg):
    code, out, err = run(capsys, *argv)
    assert code == 2
    assert msg in err and err.count("\n") == 1 and "Traceback" not in err


def test_bad_group_is_refused(tmp_path, capsys):
    scene = tmp_path / "row.yaml"
    run(capsys, "scene", "generate", "--kind", "row", "--class", "2", "-o", str(scene))
    code, _, err = run(capsys, "check", str(scene), "--grasp", "0", "0", "0", "--group", "0", "7")
    assert code == 2 and "--group names object 7" in err


def test_console_script_exit_code(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("objects:\n- {shape: banana, pose: [0, 0, 0]}\n")
    r = subprocess.run(
        [sys.executable, "-m", "mog_drake.cli", "check", str(bad), "--grasp", "0", "0", "0"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2
    assert r.stderr.strip().startswith("mog-drake: error:") and "banana" in r.stderr


def test_scene_show_with_a_grasp(tmp_path, capsys):
    scene = tmp_path / "row.yaml"
    run(capsys, "scene", "generate", "--kind", "row", "--class", "2", "-o", str(scene))
    png = tmp_path / "g.png"
    code, _, err = run(capsys, "scene", "show", str(scene), "--grasp", "0", "0", "0", "-o", str(png))
    assert code == 0 and png.stat().st_size > 10_000, err
    code, _, err = run(capsys, "bench", "verifier", "--tables", "-1")
    assert code == 2 and "--tables must be at least 0, got -1" in err and err.count("\n") == 1
    code, _, err = run(capsys, "bench", "rest", "--scenes", "26")
    assert code == 2 and "copies per shape (--scenes) must be 1..25, got 26" in err and err.count("\n") == 1
    uncapped = tmp_path / "uncapped.yaml"
    uncapped.write_text("planner:\n  grasp:\n    max_physics_large: null\n")
    code, _, err = run(capsys, "bench", "replanning", "--scenario", str(uncapped))
    assert (
        code == 2
        and "uncapped.yaml sets none below planner.grasp.max_physics" in err
        and err.count("\n") == 1
    )


def test_every_eval_takes_summary_only(tmp_path, capsys):
    from mog_drake.experiments import conditions

    conditions.run([2], 1, seed=3, out_dir=tmp_path, progress=False, n_positions=4, n_orientations=2)
    code, out, _ = run(
        capsys,
        *"eval conditions --classes 2 --scenes-per-class 2 --seed 3 --positions 4 --orientations 2".split(),
        "--out",
        str(tmp_path),
        "--summary-only",
        "--json",
    )
    assert code == 0 and json.loads(out)["rows"][0]["scenes"] == 1  # the second scene was not run
    for e in ("planner", "picking"):
        with pytest.raises(SystemExit) as ex:
            main(["eval", e, "--help"])
        assert ex.value.code == 0 and "--summary-only" in capsys.readouterr().out


def test_picking_sweeps_compare_from_the_command_line(tmp_path, capsys):
    from mog_drake.experiments.picking_eval import tasks

    def sweep(folder, pph):
        folder.mkdir()
        lines = []
        for t in tasks(2, ["mog"], seed=0, objects=33, time_limit=900.0):
            summary = {
                "success_rate": 1.0,
                "picked_pct": 100.0,
                "objects_per_success": 1.5,
                "pph": pph + t["scene"],
                "attempts": 20,
                "robot_time_s": 150.0,
                "planning_time_s": 100.0,
            }
            lines.append(json.dumps({**t, "summary": summary, "attempts": []}))
        (folder / "results.jsonl").write_text("\n".join(lines) + "\n")
        params = {"experiment": "picking", "seed": 0, "modes": ["mog"], "objects": 33, "time_limit": 900.0}
        (folder / "sweep.json").write_text(json.dumps({**params, "scenes": 2}))

    sweep(tmp_path / "a", 400.0)
    sweep(tmp_path / "b", 450.0)
    args = "eval picking --scenes 2 --modes mog --seed 0 --summary-only".split()
    code, out, err = run(
        capsys, *args, "--out", str(tmp_path / "b"), "--compare", str(tmp_path / "a"), "--json"
    )
    assert code == 0, err
    (pph,) = [r for r in json.loads(out)["compare"]["rows"] if r["metric"] == "pph"]
    assert (pph["tables"], pph["b_minus_a"], pph["ci"]) == (2, 50.0, 0.0)
    code, _, err = run(capsys, *args, "--out", str(tmp_path / "b"), "--compare", str(tmp_path / "nowhere"))
    assert code == 2 and "--compare:" in err and "does not exist" in err


def test_every_option_says_what_it_takes_and_its_default():
    """`--help`: every option that takes a value says its default (or that it is required),
    and every command and option has a line of help."""
    import argparse

    from mog_drake.cli import build_parser

    def walk(parser, path):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    yield from walk(sub, [*path, name])
            elif not isinstance(action, argparse._HelpAction):
                yield path, action

    missing = []
    for path, action in walk(build_parser(), []):
        name = " ".join(path) + " " + (action.option_strings[-1] if action.option_strings else action.dest)
        text = action.help or ""
        takes_value = action.option_strings and action.nargs != 0
        if not text or (takes_value and not action.required and "default" not in text):
            missing.append(name)
    assert not missing, missing
