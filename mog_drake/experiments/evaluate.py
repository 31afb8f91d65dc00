"""`mog-drake eval`: the three experiments, each a resumable sweep in its own folder, run or
summarised from the command line's options."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from mog_drake.errors import MogError


def parse_classes(text: str) -> list[int]:
    """Row classes from "2-7" or "2,3,5"."""
    from mog_drake.scenes import ROW_CLASSES

    try:
        if "-" in text:
            a, b = (int(v) for v in text.split("-"))
            classes = list(range(a, b + 1))
        else:
            classes = [int(v) for v in text.split(",")]
    except ValueError:
        raise MogError(f"--classes must look like 2-7 or 2,3,5, got {text!r}") from None
    bad = [c for c in classes if c not in ROW_CLASSES]
    if bad or not classes:
        raise MogError(f"--classes: {bad or text} not among the row classes {sorted(ROW_CLASSES)}")
    return classes


def parse_names(text: str, known, flag: str) -> list[str]:
    """A comma-separated list, each of ``known``."""
    names = [m.strip() for m in text.split(",") if m.strip()]
    bad = [m for m in names if m not in known]
    if bad or not names:
        raise MogError(f"{flag}: unknown {bad or repr(text)} (known: {', '.join(known)})")
    return names


LATENCY_WORDS = {"cpu": "CPU time", "measured": "wall time", "fixed": "fixed times"}


def sweep_latency(scenario: str) -> tuple[str, str]:
    """(scenario text, latency mode) of a picking sweep: the scenario's own latency mode, or
    ``cpu`` where it sets none (a sweep's results then do not depend on the machine's load, as
    a wall-clock latency would make them, nor on how many jobs share its cores). The mode is
    written into the text, which the sweep records: its folder says how it was run."""
    import yaml

    doc = yaml.safe_load(scenario) if scenario.strip() else {}
    doc = doc if isinstance(doc, dict) else {}
    latency = doc.get("latency") if isinstance(doc.get("latency"), dict) else {}
    if "mode" in latency:
        return scenario, str(latency["mode"])
    addition = "latency:\n  mode: cpu\n" if "latency" not in doc else None
    if addition is None:  # a latency section without a mode: the mode goes into it
        doc["latency"] = {**latency, "mode": "cpu"}
        return yaml.safe_dump(doc, sort_keys=False), "cpu"
    return (scenario.rstrip("\n") + "\n" if scenario.strip() else "") + addition, "cpu"


def evaluate(
    experiment: str, out: str, summary_only: bool = False, jobs: int | None = None, **o
) -> tuple[dict, str]:
    """Runs (or with ``summary_only`` only summarises) ``experiment`` into ``out``; returns its
    summary and the text report. ``o``: the command line's options, by their names."""
    from mog_drake.experiments.sweep import summary_only as reading

    common = {"jobs": jobs or os.cpu_count() or 1, "ray_address": o["ray"], "progress": o["progress"]}
    out = Path(out)
    with reading() if summary_only else contextlib.nullcontext():
        if experiment == "picking":
            from mog_drake.experiments import picking_eval
            from mog_drake.planning.config import MODES
            from mog_drake.scenario import scenario_from_text

            scenario = ""
            if o["scenario"]:
                from mog_drake.files import read_text
                from mog_drake.scenario import load_scenario, scenario_path

                load_scenario(o["scenario"])  # refuses a bad file before anything runs
                scenario = read_text(scenario_path(o["scenario"]), "scenario file")
            from mog_drake.experiments.sweep import read_params, same_param

            recorded = (read_params(out) or {}).get("scenario", "")
            if same_param("scenario", recorded, scenario) and (out / "sweep.json").exists():
                # A sweep made before sweeps defaulted to the CPU clock: read or resumed as it was made.
                mode = str(scenario_from_text(scenario).latency.mode) if scenario else "measured"
            else:
                scenario, mode = sweep_latency(scenario)
            note = f"picking: perception and planning take their {LATENCY_WORDS.get(mode, mode)} in simulated time (latency.mode {mode})"
            modes = parse_names(o["modes"], MODES, "--modes")
            summary, results = picking_eval.run(
                o["scenes"], modes, o["seed"], out, o["objects"], o["time_limit"],
                scenario=scenario, compare_dir=o["compare"], note=note, **common,
            )  # fmt: skip
            return summary, picking_eval.report(summary, results, out, o["compare"])
        grid = {"n_positions": o["positions"], "n_orientations": o["orientations"], **common}
        classes = parse_classes(o["classes"])
        if experiment == "conditions":
            from mog_drake.experiments import conditions

            summary, _ = conditions.run(classes, o["scenes_per_class"], o["seed"], out, **grid)
            return summary, conditions.report(summary, out)
        from mog_drake.experiments import planning_eval
        from mog_drake.planning.config import METHODS

        methods = parse_names(o["methods"], METHODS, "--methods")
        summary, _ = planning_eval.run(
            classes,
            o["scenes_per_class"],
            o["seed"],
            out,
            methods=methods,
            max_physics=o["max_physics"],
            **grid,
        )
        return summary, planning_eval.report(summary, out)
