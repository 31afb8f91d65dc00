"""Bad input gets one line and exit 2 (or a correct result), never a traceback or a false
success; machine-readable output is strict JSON; sweeps stay whole."""

import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mog_drake.cli import main
from mog_drake.errors import MogError
from mog_drake.scenario import scenario_from_text
from mog_drake.scenes import Scene


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def one_line_error(code, err, *words):
    assert code == 2, err
    assert err.startswith("mog-drake: error: ") and err.count("\n") == 1, err
    for w in words:
        assert w in err, err


def strict_json(text: str):
    """json.loads that refuses NaN and Infinity, as a strict parser does."""

    def refuse(name):
        raise ValueError(f"not JSON: {name}")

    return json.loads(text, parse_constant=refuse)


# --- wrong answers ---------------------------------------------------------------------------
def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def test_an_object_far_off_the_table_is_refused(tmp_path, capsys):
    f = _write(
        tmp_path,
        "far.yaml",
        """
        objects:
        - {shape: thin_bar, pose: [0, 0, 0]}
        - {shape: thin_bar, pose: [1e15, 0, 0]}
        - {shape: thick_bar, pose: [1e15, 0, 0]}
        group: [0]
        """,
    )
    code, out, err = run(capsys, "check", f, "--grasp", 0, 0, 0, "--simulate", "--json")
    one_line_error(code, err, "object 1 (thin_bar)", "off the table")
    assert out == ""


@pytest.mark.parametrize("group,words", [("[0, 0]", "names an object twice"), ("[]", "group is empty")])
def test_a_duplicate_or_empty_group_in_a_scene_file_is_refused(tmp_path, capsys, group, words):
    f = _write(
        tmp_path,
        "g.yaml",
        f"""
        objects:
        - {{shape: thin_bar, pose: [0, 0, 0]}}
        - {{shape: thick_bar, pose: [0.1, 0, 0]}}
        group: {group}
        """,
    )
    for cmd in (["check", f, "--grasp", 0, 0, 0], ["candidates", f]):
        code, _, err = run(capsys, *cmd)
        one_line_error(code, err, words)


def test_a_grasp_starting_in_collision_is_no_success(tmp_path, capsys):
    """The issue's case: the open jaws placed across a row's objects start in penetration,
    which used to "lift" them."""
    scene = tmp_path / "row.yaml"
    assert run(capsys, "scene", "generate", "--kind", "row", "--class", 3, "--seed", 1, "-o", scene)[0] == 0
    code, out, _ = run(capsys, "check", scene, "--grasp", 16.88, 0.81, 25.71, "--simulate", "--json")
    doc = strict_json(out)
    assert code == 0 and doc["collision_free"] is False
    sim = doc["simulation"]
    assert sim["success"] is False and "collision" in sim["error"] and sim["complete"] is False


def test_faulted_physics_results_are_not_complete():
    import numpy as np

    from mog_drake.scenes import row_scene
    from mog_drake.sim.verifier import row_verifier

    scene = row_scene(2, np.random.default_rng(0))
    r = row_verifier().check(scene, scene.group, [float("nan"), 0, 0])
    assert r.error and not r.success and r.complete is False


# --- files that are not what they should be ---------------------------------------------------
def _pick(capsys, scenario):
    return run(capsys, "pick", "--scenario", scenario, "--time-limit", 1)


def test_pick_scenario_files_that_cannot_be_read(tmp_path, capsys, monkeypatch):
    one_line_error(*_pick(capsys, tmp_path / "missing.yaml")[::2], "not found")
    one_line_error(*_pick(capsys, tmp_path)[::2], "is a directory")
    binary = tmp_path / "bin.yaml"
    binary.write_bytes(bytes(range(256)) * 4)
    one_line_error(*_pick(capsys, binary)[::2], "not a text file")
    typed = _write(tmp_path, "typed.yaml", "verifier: {hold_time: abc}\n")
    one_line_error(*_pick(capsys, typed)[::2], "verifier.hold_time", "abc")
    bodies = _write(tmp_path, "bodies.yaml", "verifier: {bodies: all}\n")
    one_line_error(*_pick(capsys, bodies)[::2], "verifier.bodies", "all")
    table = _write(tmp_path, "table.yaml", "contact: {table_collision: plane}\n")
    one_line_error(*_pick(capsys, table)[::2], "contact.table_collision", "plane")
    surface = _write(tmp_path, "surface.yaml", "contact: {plant: {contact_surface_representation: quad}}\n")
    one_line_error(*_pick(capsys, surface)[::2], "contact.plant.contact_surface_representation", "quad")
    # Unreadable: as root every file is readable, so the OS's refusal is modelled.
    locked = _write(tmp_path, "locked.yaml", "time_limit: 5\n")
    import mog_drake.files as files

    def refused(path, *a, **kw):  # what open() raises on a file the user may not read
        if Path(path) == locked:
            raise PermissionError(13, "denied")
        return open(path, *a, **kw)

    monkeypatch.setattr(files, "open", refused, raising=False)
    one_line_error(*_pick(capsys, locked)[::2], "permission denied")


@pytest.mark.parametrize(
    "text,key",
    [
        ("time_limit: -5", "time_limit"),
        ("time_limit: .nan", "time_limit"),
        ("gripper: {force_limit: 1e308}", "gripper.force_limit"),
        ("gripper: {force_limit: -40}", "gripper.force_limit"),
        ("robot: {max_joint_speed: 0}", "robot.max_joint_speed"),
        ("robot: {base: [.nan, 0, 0]}", "robot.base"),
        ("table: [.nan, 0.3, -0.4, 0.4]", "table"),
        ("camera: {width: -640}", "camera.width"),
        ("scene: !RowScene {row_class: x}", "scene.row_class"),
        ("colour: red", "colour"),
        ("hardware: {gripper_timeout: 0}", "hardware.gripper_timeout"),
        ("scene: !RowScene {seed: -5}", "scene.seed"),
        ("scene: !RowScene {row_class: 9}", "scene.row_class"),
        ("scene: {n_objects: -1}", "scene.n_objects"),
        ("scene: !SceneFile {file: ''}", "scene.file"),
        ("hardware: {camera: !ReplaySource {dir: x, frame_period: 0}}", "hardware.camera.frame_period"),
        ("hardware: {camera: !ReplaySource {dir: x, frame_period: -1}}", "hardware.camera.frame_period"),
        ("hardware: {gripper_move_timeout: 1e6}", "hardware.gripper_move_timeout"),
        ("hardware: {gripper_port: 70000}", "hardware.gripper_port"),
        ("hardware: {gripper_port: 0}", "hardware.gripper_port"),
        ("planner: {seed: -1}", "planner.seed"),
        ("planner: {robust: {seed: -1}}", "planner.robust.seed"),
        ("planner: {grasp: {n_positions: 100000000}}", "planner.grasp: n_positions"),
        ("planner: {grasp: {n_orientations: 100000}}", "planner.grasp: n_positions"),
    ],
)
def test_invalid_scenario_values_are_refused_at_load_naming_the_key(text, key):
    with pytest.raises(MogError, match=f"^scenario: {key.replace('.', '[.]')}"):
        scenario_from_text(text)


@pytest.mark.parametrize("text", ["", "# nothing set\n", "---\n", "~\n"])
def test_an_empty_scenario_keeps_every_default(text):
    from mog_drake.scenario import scenario_yaml

    assert scenario_yaml(scenario_from_text(text)) == scenario_yaml(scenario_from_text("time_limit: 600.0"))


def test_a_long_list_in_a_scenario_is_refused_in_one_short_line(tmp_path, capsys):
    """2 MB on one line is over the size a scenario may have; 200 kB of numbers (under it) are
    more values than a scenario holds: both refused from one scan, the line not echoing them."""
    for n in (400_000, 45_000):
        f = tmp_path / f"long{n}.yaml"
        f.write_text("table: [" + ", ".join(["1.0"] * n) + "]\n")
        code, _, err = run(capsys, "pick", "--scenario", f)
        one_line_error(code, err, "over 1 MiB" if n > 100_000 else "more than 5,000 YAML values")
        assert len(err) < 300


@pytest.mark.parametrize(
    "text,words",
    [("bars: 3\n", "'bars' must be a list"), ("inventories: [1, 2]\n", "'inventories' must be a mapping")],
)
def test_a_shapes_file_with_wrongly_typed_sections_is_one_line(tmp_path, capsys, text, words):
    f = tmp_path / "shapes.yaml"
    f.write_text(text)
    one_line_error(*run(capsys, "shapes", "--shapes", f)[::2], words)


def test_a_reader_that_goes_away_ends_the_output_quietly():
    """`mog-drake shapes | true`: the pipe is closed before the table is written. As any Unix
    tool: no message, exit 141 (128 + SIGPIPE)."""
    p = subprocess.run(
        f"{sys.executable} -m mog_drake.cli shapes --json | true; echo ${{PIPESTATUS[0]}}",
        shell=True,
        executable="/bin/bash",
        capture_output=True,
        text=True,
    )
    assert p.stdout.strip() == "141" and p.stderr == "", p.stderr


@pytest.mark.parametrize(
    "extra,words",
    [
        ("meta: [1, 2, 3]", "'meta' must be a mapping"),
        ('meta: "x"', "'meta' must be a mapping"),
        ("shapes: 123", "'shapes' must be the path"),
        ("shapes: [a.yaml]", "'shapes' must be the path"),
    ],
)
def test_scene_files_with_wrongly_typed_fields(tmp_path, capsys, extra, words):
    f = _write(tmp_path, "s.yaml", "objects:\n- {shape: thin_bar, pose: [0, 0, 0]}\n" + extra + "\n")
    one_line_error(*run(capsys, "candidates", f)[::2], words)


def test_a_scene_with_no_objects_and_a_shape_of_absurd_height(tmp_path, capsys):
    one_line_error(
        *run(capsys, "candidates", _write(tmp_path, "e.yaml", "objects: []\n"))[::2], "at least one"
    )
    shapes = _write(
        tmp_path,
        "tall.yaml",
        "shapes:\n  tower: {vertices: [[-0.01, -0.01], [0.01, -0.01], [0.01, 0.01], [-0.01, 0.01]], height: 1e308}\n",
    )
    one_line_error(*run(capsys, "shapes", "--shapes", shapes)[::2], "tower", "height")
    sheet = _write(
        tmp_path,
        "sheet.yaml",
        "shapes:\n  sheet: {vertices: [[-0.01, -0.01], [0.01, -0.01], [0.01, 0.01], [-0.01, 0.01]], height: 1e-9}\n",
    )
    one_line_error(*run(capsys, "shapes", "--shapes", sheet)[::2], "sheet", "height must be at least")
    crowd = tmp_path / "crowd.yaml"
    crowd.write_text("objects:\n" + "- {shape: thin_bar, pose: [0, 0, 0]}\n" * 501)
    one_line_error(*run(capsys, "candidates", crowd)[::2], "501 objects; a table holds at most 500")


# --- command-line arguments -----------------------------------------------------------------------
def test_bad_arguments_get_one_line(tmp_path, capsys):
    scene = tmp_path / "row.yaml"
    assert run(capsys, "scene", "generate", "--kind", "row", "--class", 2, "--seed", 1, "-o", scene)[0] == 0
    cases = [
        (["scene", "generate", "--kind", "row", "--class", 2, "--seed", -1], "--seed"),
        (["plan", scene, "--seed", -3], "--seed"),
        (["pick", "--time-limit", "nan"], "--time-limit"),
        (["pick", "--time-limit", -1], "--time-limit"),
        (["gripper", "--ip", "127.0.0.1", "--timeout", -1, "status"], "--timeout"),
        (["scene", "show", scene, "-o", tmp_path / "x.bmpx"], "unknown file type"),
        (["scene", "show", scene, "-o", tmp_path], "is a directory"),
        (["pick", "--bogus"], "unrecognized arguments"),
        (["check", scene], "--grasp"),
        (["nonsense"], "invalid choice"),
        (["pick", "--robot-ip", "192.0.2.1"], "--robot-ip applies to a hardware scenario"),
        (["pick", "--dry-run"], "--dry-run applies to a hardware scenario"),
        (["candidates", scene, "--positions", 100_000], "--positions must be at most 10,000"),
    ]
    for argv, words in cases:
        one_line_error(*run(capsys, *argv)[::2], words)


def test_an_unwritable_output_and_a_broken_replay_frame_get_one_line(tmp_path, capsys):
    scene = tmp_path / "row.yaml"
    run(capsys, "scene", "generate", "--kind", "row", "--class", 2, "--seed", 1, "-o", scene)
    blocker = tmp_path / "file"
    blocker.write_text("x")  # a file where a folder should be: nothing can be written under it
    one_line_error(*run(capsys, "scene", "show", scene, "-o", blocker / "x.png")[::2], str(blocker))
    frames = tmp_path / "frames"
    frames.mkdir()
    (frames / "frame_0000.npz").write_bytes(b"not an npz")
    hw = _write(
        tmp_path,
        "hw.yaml",
        f"hardware: {{enabled: true, dry_run: true, max_joint_speed: 3.5, camera: !ReplaySource {{dir: '{frames}'}}}}\n",
    )
    one_line_error(
        *run(capsys, "pick", "--scenario", hw, "--robot-ip", "192.0.2.1")[::2], "not a readable frame"
    )


def test_a_grasp_pasted_from_candidates_is_the_candidate_and_one_off_the_table_is_refused(tmp_path, capsys):
    """`candidates` prints mm and degrees; `check --grasp` takes what it prints."""
    scene = tmp_path / "row.yaml"
    run(capsys, "scene", "generate", "--kind", "row", "--class", 4, "--seed", 1, "-o", scene)
    code, out, _ = run(capsys, "candidates", scene, "--json")
    doc = strict_json(out)
    passed = [r for r in doc["candidates"] if r["verdict"] == "passed"][0]
    text = run(capsys, "candidates", scene)[1]
    row = next(ln.split() for ln in text.splitlines() if ln.split()[:1] == [str(passed["rank"])])
    code, out, err = run(capsys, "check", scene, "--grasp", *row[1:4], "--json")  # as printed
    assert code == 0, err
    assert strict_json(out)["verdict"] == "passed"
    # The same numbers read as metres and radians would be 18 m off: refused, not checked.
    code, out, err = run(capsys, "check", scene, "--grasp", 18530, 7, 51, "--json")
    one_line_error(code, err, "off the scene's table", "mm and degrees")


def test_negative_numbers_in_exponent_form_are_numbers(tmp_path, capsys):
    scene = tmp_path / "row.yaml"
    run(capsys, "scene", "generate", "--kind", "row", "--class", 2, "--seed", 1, "-o", scene)
    code, out, err = run(capsys, "check", scene, "--grasp", "-1e-3", "0", "-2.5E-1", "--json")
    assert code == 0, err
    assert strict_json(out)["grasp"] == pytest.approx([-1e-6, 0.0, math.radians(-0.25)])


# --- machine-readable output -----------------------------------------------------------------
def test_pick_json_is_strict_json_even_with_no_attempt(capsys):
    # 0.1 s of robot time: the run ends before its first attempt, so every rate is undefined.
    code, out, err = run(capsys, "pick", "--objects", 1, "--seed", 0, "--time-limit", 0.1, "--json")
    assert code == 0, err
    doc = strict_json(out)
    assert doc["summary"]["attempts"] == 0 and doc["summary"]["success_rate"] is None


def test_demo_json_is_one_document(tmp_path, capsys):
    code, out, _ = run(capsys, "demo", "--out", tmp_path, "--json")
    assert code == 0
    assert [s["name"] for s in strict_json(out)["scenes"]] == ["row4", "cluttered"]


# --- sweeps -----------------------------------------------------------------------------------
def _echo(task):
    return {"key": task["key"], "value": task["value"]}


def _sleepy(task):
    time.sleep(60)
    return {"key": task["key"]}


def test_a_corrupt_line_mid_file_is_skipped_with_a_warning_and_run_again(tmp_path, capsys):
    from mog_drake.experiments.sweep import load_results, run_sweep

    tasks = [{"key": f"k{i}", "value": i} for i in range(3)]
    path = tmp_path / "results.jsonl"
    path.write_text('{"key": "k0", "value": 0}\n{"key": "k1", "val\x00garbage\n{"key": "k2", "value": 2}\n')
    assert set(load_results(path, repair=False)) == {"k0", "k2"}
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "line 2 is not a result record" in err
    results = run_sweep(tasks, _echo, tmp_path, progress=False)
    assert [r["value"] for r in results] == [0, 1, 2]
    lines = path.read_text().splitlines()
    assert len(lines) == 3 and all(json.loads(x) for x in lines)  # the corrupt line is gone


def test_a_second_sweep_on_the_same_folder_is_refused_naming_the_holder(tmp_path):
    import fcntl

    from mog_drake.experiments.sweep import run_sweep

    with open(tmp_path / ".lock", "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        f.write("4242")
        f.flush()
        with pytest.raises(MogError, match=r"in use by another sweep \(process 4242\)"):
            run_sweep([{"key": "a", "value": 1}], _echo, tmp_path, progress=False)
    assert not (tmp_path / "results.jsonl").exists()
    assert run_sweep([{"key": "a", "value": 1}], _echo, tmp_path, progress=False) == [
        {"key": "a", "value": 1}
    ]


@pytest.mark.parametrize("text", ["", "{garbage", "[1, 2]", '"picking"'])
def test_a_broken_sweep_json_is_one_line_naming_it(tmp_path, text):
    from mog_drake.experiments.sweep import check_params

    (tmp_path / "sweep.json").write_text(text)
    with pytest.raises(MogError, match=r"sweep\.json is not a sweep's parameters \(a JSON object\)"):
        check_params(tmp_path, {"experiment": "picking"})
    assert (tmp_path / "sweep.json").read_text() == text  # left for the user to look at


def test_a_sweep_into_another_experiments_folder_names_both(tmp_path):
    from mog_drake.experiments.sweep import check_params

    check_params(tmp_path, {"experiment": "picking", "seed": 0})
    with pytest.raises(MogError, match="holds a picking sweep, not a conditions one"):
        check_params(tmp_path, {"experiment": "conditions", "classes": [1]})


def test_sweep_parameters_are_recorded_under_the_folder_lock(tmp_path):
    """Two sweeps starting at once: the one that finds the folder locked records nothing (the
    other's sweep.json stays), and says who holds it."""
    import fcntl

    from mog_drake.experiments.sweep import check_params

    check_params(tmp_path, {"experiment": "picking", "seed": 0})
    with open(tmp_path / ".lock", "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        f.write("4242")
        f.flush()
        with pytest.raises(MogError, match=r"in use by another sweep \(process 4242\)"):
            check_params(tmp_path, {"experiment": "picking", "seed": 0})
    assert json.loads((tmp_path / "sweep.json").read_text()) == {"experiment": "picking", "seed": 0}


def test_records_of_the_wrong_shape_are_skipped_and_run_again(tmp_path, capsys):
    """Lines that are JSON records with a key but not what a picking summary reads (a list,
    a missing summary, a summary of words, a key that is a list) are skipped with one warning
    line each, here and when read as a --compare folder."""
    from mog_drake.experiments.picking_eval import compare, valid_run
    from mog_drake.experiments.sweep import load_results

    good = {
        "key": "mog-0",
        "mode": "mog",
        "scene_seed": 7,
        "attempts": [],
        "summary": {"pph": 500.0, "finished": "clear"},
    }
    lines = [
        good,
        [1, 2],
        {"key": ["x"], "mode": "mog"},
        {"key": "mog-1", "mode": "mog", "scene_seed": 8, "attempts": []},
        {"key": "mog-2", "mode": "mog", "scene_seed": 9, "attempts": [], "summary": {"pph": "fast"}},
    ]
    path = tmp_path / "results.jsonl"
    path.write_text("".join(json.dumps(x) + "\n" for x in lines))
    assert list(load_results(path, repair=False, valid=valid_run)) == ["mog-0"]
    err = capsys.readouterr().err
    assert err.count("\n") == 4 and all(f"line {n} is not a result record" in err for n in (2, 3, 4, 5)), err
    other = {**good, "summary": {"pph": 600.0, "finished": "clear"}}
    doc = compare(list(load_results(path, repair=False, valid=valid_run).values()), [other])
    assert doc["tables"] == 1 and doc["rows"][0]["b_minus_a"] == pytest.approx(100.0)


def test_warnings_are_one_line_and_numpy_runtime_warnings_none(monkeypatch, capsys):
    import warnings

    import numpy as np

    from mog_drake import cli

    def noisy(args):
        warnings.warn("frames recorded\n  without intrinsics", stacklevel=1)
        return 0 if np.isnan(np.mean([])) else 1  # numpy's "Mean of empty slice"

    monkeypatch.setattr(cli.geometry, "cmd_shapes", noisy)
    code, out, err = run(capsys, "shapes")
    assert code == 0 and err == "mog-drake: warning: frames recorded without intrinsics\n", err


def test_summary_only_writes_nothing(tmp_path, capsys):
    out = tmp_path / "p"
    argv = ["eval", "picking", "--scenes", "1", "--modes", "sog", "--objects", "1", "--time-limit", "10"]
    assert main([*argv, "--out", str(out), "--jobs", "1"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    # A summary of a subset (no tables asked for beyond the one run) only reads.
    assert main([*argv, "--out", str(out), "--summary-only"]) == 0
    assert "summary only: nothing written" in capsys.readouterr().out
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_workers_exit_when_their_parent_is_killed(tmp_path):
    script = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_bad_input import _sleepy
        from mog_drake.experiments.sweep import run_sweep
        run_sweep([{{"key": "a"}}, {{"key": "b"}}], _sleepy, {str(tmp_path)!r}, jobs=2, progress=False)
        """
    )
    parent = subprocess.Popen([sys.executable, "-c", script])

    def children(pid):
        out = []
        for d in Path("/proc").iterdir():
            if d.name.isdigit():
                try:
                    if int((d / "stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                        out.append(int(d.name))
                except (OSError, IndexError, ValueError):
                    pass
        return out

    for _ in range(200):  # the pool's two workers start (bounded wait)
        kids = children(parent.pid)
        if len(kids) >= 2:
            break
        time.sleep(0.1)
    assert len(kids) >= 2
    time.sleep(1.0)  # the workers are inside their 60 s task
    os.kill(parent.pid, signal.SIGKILL)
    parent.wait()
    for _ in range(100):  # bounded: they must go long before their task would end
        alive = [
            k
            for k in kids
            if Path(f"/proc/{k}").exists()
            and "Z" not in (Path(f"/proc/{k}/stat").read_text().rsplit(")", 1)[1].split()[0])
        ]
        if not alive:
            break
        time.sleep(0.1)
    assert not alive


# --- random malformed files fed to the loaders ------------------------------------------------
_leaf = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**20), 10**20),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e308, -1e308, 1e-320, 3e14, -0.0]),
    st.text(max_size=6),
)
_value = st.recursive(
    _leaf,
    lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=6), c, max_size=3),
    max_leaves=8,
)
_pose = st.lists(
    st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([1e15, -3e14, 0.05])),
    min_size=0,
    max_size=4,
)
_object = st.fixed_dictionaries(
    {
        "shape": st.one_of(st.sampled_from(["thin_bar", "thick_bar", "red_triangle", "nope"]), _leaf),
        "pose": st.one_of(_pose, _leaf),
    }
)
_scene_doc = st.fixed_dictionaries(
    {"objects": st.one_of(st.lists(_object, max_size=4), _leaf)},
    optional={
        "group": st.one_of(st.lists(st.integers(-2, 5), max_size=4), _leaf),
        "table": st.one_of(st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5), _leaf),
        "meta": _value,
        "shapes": _value,
    },
)


def _valid_scene(scene: Scene) -> None:
    x0, x1, y0, y1 = scene.table
    assert len(scene) >= 1 and x0 < x1 and y0 < y1
    for o in scene.objects:
        assert all(math.isfinite(v) for v in o.pose) and x0 <= o.x <= x1 and y0 <= o.y <= y1
        assert o.shape in scene.library.shapes
    if scene.group is not None:
        assert scene.group and len(set(scene.group)) == len(scene.group)
        assert all(0 <= g < len(scene) for g in scene.group)
    assert all(p.is_valid and p.area > 0 for p in scene.shapely_polygons())


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_scene_doc)
def test_random_malformed_scene_files_end_in_a_mog_error_or_a_valid_scene(doc):
    try:
        scene = Scene.from_dict(doc)
    except MogError:
        return
    _valid_scene(scene)


_scenario_keys = st.sampled_from(
    [
        "time_limit",
        "table",
        "robot.base",
        "robot.max_joint_speed",
        "robot.reach",
        "gripper.force_limit",
        "gripper.close_speed",
        "camera.width",
        "camera.z_far",
        "verifier.hold_time",
        "verifier.hold_window",
        "planner.loop.group_radius",
        "planner.mode",
        "planner.grasp.diameter_condition",
        "verifier.bodies",
        "planner.pushes.speed",
        "planner.pushes.max_per_table",
        "planner.grasp.max_physics",
        "planner.grasp.min_squeeze_margin_deg",
        "latency.mode",
        "contact.plant.time_step",
        "contact.table_collision",
        "contact.plant.contact_surface_representation",
        "controller.period",
        "bin.depth",
        "hardware.max_joint_speed",
        "hardware.workspace",
    ]
)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(_scenario_keys, _value), min_size=1, max_size=3))
def test_random_malformed_scenarios_end_in_a_mog_error_or_a_checked_scenario(pairs):
    doc: dict = {}
    for key, value in pairs:
        node = doc
        *parents, last = key.split(".")
        for k in parents:
            node = node.setdefault(k, {})
        node[last] = value
    try:
        text = yaml.safe_dump(doc)
    except yaml.YAMLError:
        return
    try:
        sc = scenario_from_text(text)
    except MogError:
        return
    # Accepted: it must then be a scenario every check passes, with nothing non-finite in it.
    from mog_drake.scenario import _finite_leaves, check_scenario

    check_scenario(sc)
    assert all(math.isfinite(v) for _, v in _finite_leaves(sc))


def test_an_unwritable_record_path_is_refused_before_the_run(tmp_path, capsys, monkeypatch):
    """A --record path under a file cannot be written: one line and exit 2, before any run."""
    import mog_drake.systems.pick as pick

    monkeypatch.setattr(pick, "run_pick", lambda *a, **kw: pytest.fail("the run started"))
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    code = main(["pick", "--objects", "2", "--record", str(blocker / "replay.html")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "--record" in err and "cannot be written" in err, err


def test_a_write_cut_short_leaves_the_earlier_file_whole(tmp_path):
    from mog_drake.files import atomic_path, write_atomic

    path = write_atomic(tmp_path / "replay.html", "<html>earlier</html>")
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(path) as tmp:
            tmp.write_text("<html>half of a new")
            raise KeyboardInterrupt  # a signal in the middle of the write
    assert path.read_text() == "<html>earlier</html>"
    assert [p.name for p in tmp_path.iterdir()] == ["replay.html"]  # no temporary left behind


@pytest.mark.parametrize(
    "text,expected",
    [
        (
            "a: &a [1, 1]\n"
            + "".join(
                f"a{k}: &a{k} [*a{'' if k == 0 else k - 1}, *a{'' if k == 0 else k - 1}]\n" for k in range(60)
            ),
            "YAML aliases",
        ),
        ("x: " + "[" * 200 + "]" * 200 + "\n", "nested more than"),
    ],
)
def test_yaml_that_would_expand_past_memory_or_recursion_is_refused_unread(tmp_path, capsys, text, expected):
    """An alias bomb (each level doubles: 2**60 copies) and 200 nested lists: one line, exit 2,
    from a scan of the tokens (nothing is expanded), as a scenario and as a scene."""
    f = tmp_path / "bomb.yaml"
    f.write_text(text)
    for argv in (["pick", "--scenario", str(f)], ["candidates", str(f)]):
        code, _, err = run(capsys, *argv)
        assert code == 2 and expected in err and err.count("\n") == 1, err


def test_devices_and_fifos_are_refused_as_files(tmp_path, capsys):
    """/dev/zero never ends and a FIFO blocks a reader forever: neither is read."""
    fifo = tmp_path / "scene.fifo"
    os.mkfifo(fifo)
    for path in ("/dev/zero", str(fifo)):
        code, _, err = run(capsys, "candidates", path)
        assert code == 2 and "not a regular file" in err and err.count("\n") == 1, err


@pytest.mark.parametrize("name", ["results.jsonl", "sweep.json", "failures.jsonl"])
def test_a_fifo_in_a_sweep_folder_is_refused_in_one_line(tmp_path, capsys, name):
    """A FIFO where a sweep's file belongs would block `eval` for good: with --out, with
    --summary-only and as --compare's folder, it is refused in one line, at once."""
    sweep = tmp_path / "sweep"
    argv = ["eval", "picking", "--scenes", 1, "--modes", "mog", "--objects", 1, "--time-limit", 0.1]
    assert run(capsys, *argv, "--out", sweep, "--jobs", 1)[0] == 0
    bad = tmp_path / "bad"
    bad.mkdir()
    for f in sweep.iterdir():
        if f.name != name and f.is_file() and not f.name.startswith("."):
            (bad / f.name).write_bytes(f.read_bytes())
    (bad / name).unlink(missing_ok=True)
    os.mkfifo(bad / name)
    cases = [["--out", bad, "--jobs", 1]]
    if name != "failures.jsonl":  # appended to by a run only; a summary and --compare read the others
        cases += [
            ["--out", bad, "--summary-only"],
            ["--out", tmp_path / "fresh", "--jobs", 1, "--compare", bad],
        ]
    for extra in cases:
        code, _, err = run(capsys, *argv, *extra)
        one_line_error(code, err, "not a regular file")


def test_a_fifo_as_a_recorded_frame_is_refused_in_one_line(replay_dir, tmp_path, capsys):
    frames = tmp_path / "frames"
    frames.mkdir()
    for f in Path(replay_dir).iterdir():
        (frames / f.name).write_bytes(f.read_bytes())
    os.mkfifo(frames / "frame_9999.npz")
    scenario = tmp_path / "replay.yaml"
    scenario.write_text(
        f"hardware: {{camera: !ReplaySource {{dir: '{frames}'}}, enabled: true, dry_run: true, max_joint_speed: 3.5}}\n"
    )
    code, _, err = run(capsys, "pick", "--scenario", scenario, "--robot-ip", "127.0.0.1", "--dry-run")
    one_line_error(code, err, "frame_9999.npz", "not a regular file")


def test_sigterm_twice_stops_a_sweep_with_143_and_stores_nothing_half_done(tmp_path):
    """`kill` twice in a row while `eval conditions --jobs 1` checks grasps in physics: the
    first signal ends the sweep through its cleanup (the second one, arriving during it, is
    ignored), the process exits 143 with one line, and no check the signal cut short is
    stored as a result."""
    out = tmp_path / "sweep"
    argv = ["eval", "conditions", "--jobs", "1", "--classes", "2-7", "--scenes-per-class", "5"]
    p = subprocess.Popen(
        [sys.executable, "-m", "mog_drake.cli", *argv, "--out", str(out)],
        stderr=subprocess.PIPE,
        text=True,
    )
    for _ in range(300):  # bounded: the sweep has started once it wrote its description
        if (out / "sweep.json").exists():
            break
        time.sleep(0.05)
    time.sleep(1.5)  # inside a physics check
    p.send_signal(signal.SIGTERM)
    time.sleep(0.02)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 143, err
    assert err.splitlines()[-1] == "mog-drake: terminated by SIGTERM"
    stored = (out / "results.jsonl").read_text()
    assert "simulation failed" not in stored and "Terminated" not in stored
