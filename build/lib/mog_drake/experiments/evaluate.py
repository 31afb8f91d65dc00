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

            scenario = ""
            if o["scenario"]:
                from mog_drake.files import read_text
                from mog_drake.scenario import load_scenario

                load_scenario(o["scenario"])  # refuses a bad file before anything runs
                scenario = read_text(o["scenario"], "scenario file")
            modes = parse_names(o["modes"], MODES, "--modes")
            summary, results = picking_eval.run(
                o["scenes"], modes, o["seed"], out, o["objects"], o["time_limit"],
                scenario=scenario, compare_dir=o["compare"], **common,
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
