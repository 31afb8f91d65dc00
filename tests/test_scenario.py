"""The scenario: its file, its defaults, and its checks (each section owns its check(), and
loading calls each once)."""

import dataclasses

import pytest

from mog_drake.errors import MogError
from mog_drake.scenario import RowScene, Scenario, check_scenario, load_scenario

# Drake's own config structs: their keys are checked where they are read (the finite-number
# pass covers every one of their numbers).
DRAKE_SECTIONS = {"camera", "simulator", "visualization"}


def _sections(sc):
    return [
        (f.name, getattr(sc, f.name))
        for f in dataclasses.fields(sc)
        if dataclasses.is_dataclass(getattr(sc, f.name)) and f.name not in DRAKE_SECTIONS
    ]


def test_every_section_owns_a_check_that_loading_calls_once(monkeypatch):
    sc = Scenario()
    calls = {}
    for name, section in _sections(sc):
        assert callable(getattr(section, "check", None)), f"scenario section {name} has no check()"
        original = type(section).check

        def counted(self, *args, _name=name, _original=original, **kw):
            calls[_name] = calls.get(_name, 0) + 1
            return _original(self, *args, **kw)

        monkeypatch.setattr(type(section), "check", counted)
    check_scenario(sc)
    # The verifier's contact is a ContactConfig as the world's is: two calls, one per section.
    expected = {name: 1 for name, _ in _sections(sc)} | {"contact": 2}
    assert calls == expected


@pytest.mark.parametrize(
    "text, message",
    [
        ("perception: {max_height: 0.001}", r"perception\.max_height"),
        ("perception: {min_fraction: 1.5}", r"perception\.min_fraction"),
        ("robot: {kd: -1}", r"robot\.kd"),
        ("bin: {wall: 0.5}", r"bin\.wall"),
        ("gripper: {close_speed: 2}", r"gripper\.close_speed"),
        ("verifier: {contact: {mu_table: -0.1}}", r"verifier\.contact\.mu_table"),
        ("latency: {mode: sometimes}", r"latency\.mode"),
        ("hardware: {camera: !RealSenseSource {fps: 0}}", r"hardware\.camera\.fps"),
        ("planner:\n  grasp:\n    method: fastest\n", "planner.grasp: unknown planner method 'fastest'"),
        ("robot:\n  reach: 0.0\n", r"robot.reach must be in \(0, 2\], got 0.0"),
        ("verifier:\n  hold_time: 0\n", "verifier.hold_time must be in"),
        ("planner:\n  loop:\n    group_radius: 35\n", "group_radius must be in .* got 35"),  # mm by mistake
        (
            "verifier:\n  hold_window: 3.0\n",
            r"verifier.hold_window must be in \[0, hold_time = 2.5\] s, got 3.0",
        ),
        (
            "planner:\n  loop:\n    grouping: nearest\n",
            "planner.loop.grouping must be one of radius, conditions, got 'nearest'",
        ),
    ],
)
def test_a_bad_setting_in_a_scenario_file_is_refused_naming_its_key(tmp_path, text, message):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(MogError, match=message):
        load_scenario(str(f))


def test_scenario_yaml_overrides_defaults(tmp_path):
    f = tmp_path / "s.yaml"
    f.write_text("scene: !RowScene {row_class: 4, seed: 3}\nplanner: {mode: sog}\ntime_limit: 30.0\n")
    sc = load_scenario(str(f))
    assert (
        isinstance(sc.scene, RowScene)
        and sc.scene.row_class == 4
        and sc.planner.mode == "sog"
        and sc.time_limit == 30
    )
    assert sc.camera.width == 640  # untouched defaults remain
    bad = tmp_path / "bad.yaml"
    bad.write_text("scene: {colour: red}\n")
    with pytest.raises(MogError, match="bad.yaml"):
        load_scenario(str(bad))


def test_committed_scenario_file_matches_the_defaults():
    from mog_drake.scenario import SCENARIO_YAML, scenario_yaml

    text = SCENARIO_YAML.read_text()
    body = "\n".join(line for line in text.splitlines() if not line.startswith("#"))
    assert body.strip() == scenario_yaml().strip()
    assert scenario_yaml(load_scenario(str(SCENARIO_YAML))) == scenario_yaml(Scenario())


def test_every_setting_is_reachable_from_yaml():
    """Every field of every nested config, the project's dataclasses and Drake's structs alike,
    is a key of models/scenario.yaml, so it can be set from a scenario file."""
    import yaml

    from mog_drake.scenario import SCENARIO_YAML

    class Untagged(yaml.SafeLoader):  # a variant's tag (!FovDegrees, !Rpy, ...) names its type only
        pass

    Untagged.add_multi_constructor("!", lambda loader, tag, node: loader.construct_mapping(node, deep=True))
    doc = yaml.load(SCENARIO_YAML.read_text(), Loader=Untagged)  # noqa: S506

    def fields(obj):
        if dataclasses.is_dataclass(obj):
            return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}
        if type(obj).__name__.endswith("Config") and hasattr(type(obj), "__fields__"):  # Drake's
            return {f.name: getattr(obj, f.name) for f in type(obj).__fields__}
        return None

    missing = []

    def walk(obj, node, path):
        for name, value in (fields(obj) or {}).items():
            if value is None:
                continue  # an optional Drake field left unset: yaml_dump_typed omits it
            if not isinstance(node, dict) or name not in node:
                missing.append(f"{path}{name}")
            elif fields(value):
                walk(value, node[name], f"{path}{name}.")

    walk(Scenario(), doc, "")
    assert not missing
    for name in ("motion", "controller", "perception", "simulator", "visualization", "camera"):
        assert name in doc
