"""Every file we ship is loaded: each scenario in models/ and results/, the shape library, the
arm's URDF, and the hardware scenario's own dry run (through the replay camera)."""

from dataclasses import replace
from pathlib import Path

import pytest

from mog_drake.hardware.config import ReplaySource
from mog_drake.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
MODELS = sorted((ROOT / "models").iterdir())
SCENARIOS = [p for p in MODELS if p.name not in ("shapes.yaml", "ur5.urdf")]
SWEEP_SCENARIOS = sorted((ROOT / "results").glob("*.yaml"))


def test_models_holds_only_files_these_tests_load():
    assert {p.name for p in MODELS} == {"shapes.yaml", "ur5.urdf", *(p.name for p in SCENARIOS)}
    assert all(p.suffix == ".yaml" for p in SCENARIOS)


@pytest.mark.parametrize("path", SCENARIOS + SWEEP_SCENARIOS, ids=lambda p: p.name)
def test_every_shipped_scenario_loads(path):
    load_scenario(str(path))


def test_the_shape_library_and_the_arm_load():
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    from mog_drake.scenes.library import DEFAULT_SHAPES_FILE, ShapeLibrary
    from mog_drake.sim.ur5 import URDF_PATH

    lib = ShapeLibrary.load(base=DEFAULT_SHAPES_FILE)
    assert len(lib.inventory("isrr33")) == 33
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(URDF_PATH))
    plant.Finalize()
    revolute = [
        plant.get_joint(j) for j in plant.GetJointIndices() if plant.get_joint(j).num_positions() == 1
    ]
    assert len(revolute) == 6  # the UR5's six joints


def test_the_hardware_scenario_dry_runs_through_the_replay_camera(replay_dir, tmp_path):
    """The runbook's first command (`pick --scenario models/hardware.yaml --dry-run`), with
    recorded frames in place of the RealSense: it perceives, plans and logs arm and gripper
    commands within the scenario's own limits."""
    import json

    from mog_drake.systems.pick import run_pick

    sc = load_scenario(str(ROOT / "models" / "hardware.yaml"))
    log = tmp_path / "commands.jsonl"
    sc.hardware = replace(
        sc.hardware,
        robot_ip="192.0.2.1",
        dry_run=True,
        command_log=str(log),
        camera=ReplaySource(dir=str(replay_dir)),
    )
    sc.time_limit = 8.0
    run_pick(sc)
    lines = [json.loads(x) for x in log.read_text().splitlines()]
    assert {x["device"] for x in lines} == {"ur5", "robotiq"}


# Placeholders of the documented commands, and values that stand for them.
PLACEHOLDERS = {"FILE": "models/scenario.yaml", "S": "1", "N": "2", "DIR": "out/x", "ADDRESS": "192.0.2.1"}


def _documented_commands() -> list[str]:
    """Every ``mog-drake ...`` command of the README and the runbook: the lines of their code
    blocks (comments cut) and the ones quoted inline."""
    import re

    commands = []
    for doc in ("README.md", "docs/hardware.md"):
        for line in (ROOT / doc).read_text().splitlines():
            if line.strip().startswith("mog-drake "):
                commands.append(line.split("  #")[0].strip())
            else:
                commands += re.findall(r"`(mog-drake [^`]*)`", line)
    return commands


def _variants(command: str) -> list[list[str]]:
    """The argument lists a documented command stands for: each ``[optional]`` part left out
    and put in (its first alternative), each ``a | b`` alternative on its own."""
    import re

    command = command.replace("--grasp X_MM Y_MM THETA_DEG", "--grasp 0 0 0")
    command = command.replace("--board-at X_MM Y_MM YAW_DEG", "--board-at 0 0 0")
    bare = re.sub(r"\s*\[[^\]]*\]", "", command)
    full = re.sub(r"\[([^\]|]*)(\|[^\]]*)?\]", r"\1", command)
    out = []
    for text in (bare, full):
        words = text.split()[1:]
        head = [w for w in words if w != "|"]
        if "|" in words:  # "bench a | b | c", "gripper ... open | close | status"
            k = words.index("|") - 1
            alternatives = [w for w in words[k:] if w != "|"]
            head = words[:k]
            out += [head + [a] for a in alternatives]
        else:
            out.append(head)
    return [[PLACEHOLDERS.get(w, w) for w in args] for args in out]


def test_every_documented_command_parses():
    """Each command the README and the runbook show is one the CLI accepts (flags, choices),
    with and without its optional parts."""
    from mog_drake.cli import build_parser

    commands = _documented_commands()
    assert len(commands) >= 15, commands
    for command in commands:
        for args in _variants(command):
            build_parser().parse_args(args)  # a usage error raises


def test_the_paper_cell_is_the_cell_its_results_ran_on():
    """models/paper_cell.yaml's numbers (README, docs/experiments.md) come from picking_v60_low,
    mog and sog on one scenario. A change to one without the other would leave the model's
    documented results for another cell."""
    cell = load_scenario(str(ROOT / "models" / "paper_cell.yaml"))
    ran = load_scenario(str(ROOT / "results" / "picking_v60_low.yaml"))
    assert ran.gripper.finger_clearance == 0.0015  # the setting v60 measured
    for part in ("realism", "gripper", "planner", "perception", "controller", "latency", "scene", "table"):
        assert getattr(cell, part) == getattr(ran, part), part
