"""The scenario's checks: each section owns its check(), and loading calls each once."""

import dataclasses

import pytest

from mog_drake.errors import MogError
from mog_drake.scenario import Scenario, check_scenario, scenario_from_text

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
    "text, key",
    [
        ("perception: {max_height: 0.001}", "perception.max_height"),
        ("perception: {min_fraction: 1.5}", "perception.min_fraction"),
        ("robot: {kd: -1}", "robot.kd"),
        ("bin: {wall: 0.5}", "bin.wall"),
        ("gripper: {close_speed: 2}", "gripper.close_speed"),
        ("verifier: {contact: {mu_table: -0.1}}", "verifier.contact.mu_table"),
        ("latency: {mode: sometimes}", "latency.mode"),
        ("hardware: {camera: !RealSenseSource {fps: 0}}", "hardware.camera.fps"),
    ],
)
def test_a_bad_key_is_refused_by_its_sections_check_naming_it(text, key):
    with pytest.raises(MogError, match=key.replace(".", r"\.")):
        scenario_from_text(text)
