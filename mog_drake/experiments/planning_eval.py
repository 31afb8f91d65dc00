"""Experiment 2 (paper Sec. 7.3): planning time and physics checks of GP vs its baselines.

Every method plans on the same seeded row scenes in the same run. The verifier is
deterministic, so within a scene each candidate is simulated once (`SceneMemo`): a method that
tests a candidate another method already simulated gets the same verdict and is charged the
wall time that simulation measured, and each method is charged one plant build, as a planner
in a new scene would pay. GP plans first, so its physics is always timed live. Each method's
record says how many of its checks were replayed (``times.replayed_checks``).
"""

from __future__ import annotations

import numpy as np

from mog_drake.experiments.conditions import row_tasks
from mog_drake.experiments.stats import mean_ci, proportion_ci
from mog_drake.experiments.sweep import check_params, run_sweep

PAPER_METHODS = ("gp", "rand-phys", "rank-phys", "rand-fil-phys")
#: The summary's columns, in the order tables print them.
COLUMNS = ["class", "method", "scenes", "time_s", "time_ci", "tested", "tested_ci", "found_pct", "gp_speedup"]


class SceneMemo:
    """A verifier for one scene that simulates each candidate once and replays it after.

    ``start_method()`` opens a method's account; ``charged`` is then the wall time its
    replayed checks (and its plant build, if the shared plant was already built) measured
    when they really ran. The wrapped verifier must be deterministic (it is: every check
    starts from the same default context).
    """

    def __init__(self, verifier):
        self.verifier = verifier
        self._results: dict[tuple, object] = {}
        self._build_time = 0.0
        self.charged = 0.0
        self.replayed = 0
        self._first = True

    def start_method(self) -> None:
        self.charged, self.replayed, self._first = 0.0, 0, True

    def check(self, scene, group, grasp):
        key = (tuple(int(g) for g in group), tuple(round(float(v), 9) for v in grasp))
        hit = self._results.get(key)
        if hit is None:
            r = self.verifier.check(scene, group, grasp)
            if r.built:
                self._build_time = getattr(self.verifier, "last_build_time", 0.0)
            elif self._first:
                self.charged += self._build_time  # this method's own plant build
            self._results[key] = (r, r.wall_time - (self._build_time if r.built else 0.0))
            self._first = False
            return r
        r, run_time = hit
        self.charged += run_time + (self._build_time if self._first else 0.0)
        self.replayed += 1
        self._first = False
        return r


def planner_worker(task: dict) -> dict:
    from mog_drake.planning.planner import GraspConfig, GraspPlanner
    from mog_drake.scenes import row_scene
    from mog_drake.sim.verifier import row_verifier

    scene = row_scene(task["class"], np.random.default_rng(task["scene_seed"]))
    memo = SceneMemo(row_verifier())
    out = {}
    for m_index, method in enumerate(task["methods"]):
        cfg = GraspConfig(
            method=method,
            max_physics=task.get("max_physics"),
            n_positions=task["n_positions"],
            n_orientations=task["n_orientations"],
        )
        memo.start_method()
        res = GraspPlanner(memo, cfg).plan(
            scene, scene.group, rng=np.random.default_rng([task["scene_seed"], m_index])
        )
        for k in ("physics", "total"):
            res.times[k] += memo.charged
        res.times["replayed_checks"] = memo.replayed
        out[method] = res.to_dict()
    return {**task, "methods_results": out}


def summarize(results: list[dict], methods) -> dict:
    """Per class and method: mean planning time and tested candidates (95 % CI), share of
    scenes with a grasp found, and GP's speed-up over each baseline (ratio of mean times on
    the same scenes)."""
    rows = []
    classes = sorted({r["class"] for r in results})
    for label, subset in [(str(c), [r for r in results if r["class"] == c]) for c in classes] + [
        ("all", results)
    ]:
        if not subset:
            continue
        gp_time = (
            np.mean([r["methods_results"]["gp"]["times"]["total"] for r in subset])
            if "gp" in methods
            else None
        )
        for m in methods:
            recs = [r["methods_results"][m] for r in subset]
            t_mean, t_ci = mean_ci([x["times"]["total"] for x in recs])
            n_mean, n_ci = mean_ci([x["tested"] for x in recs])
            found = sum(x["found"] for x in recs)
            share, lo, hi = proportion_ci(found, len(recs))
            rows.append(
                {
                    "class": label,
                    "method": m,
                    "scenes": len(recs),
                    "time_s": t_mean,
                    "time_ci": t_ci,
                    "tested": n_mean,
                    "tested_ci": n_ci,
                    "found_pct": 100 * share,
                    "found_lo": 100 * lo,
                    "found_hi": 100 * hi,
                    "gp_speedup": (t_mean / gp_time) if gp_time else float("nan"),
                }
            )
    return {"rows": rows}


def run(
    classes,
    scenes_per_class: int,
    seed: int,
    out_dir,
    *,
    methods=PAPER_METHODS,
    jobs: int = 1,
    ray_address=None,
    max_physics: int | None = None,
    progress: bool = True,
    n_positions: int = 70,
    n_orientations: int = 7,
) -> tuple[dict, list[dict]]:
    methods = list(methods)
    check_params(
        out_dir,
        {
            "experiment": "planner",
            "classes": list(classes),
            "seed": seed,
            "scenes_per_class": scenes_per_class,
            "methods": methods,
            "max_physics": max_physics,
            "n_positions": n_positions,
            "n_orientations": n_orientations,
        },
    )
    tasks = [
        {**t, "methods": methods, "max_physics": max_physics}
        for t in row_tasks(classes, scenes_per_class, seed, n_positions, n_orientations)
    ]
    results = run_sweep(
        tasks,
        planner_worker,
        out_dir,
        jobs,
        ray_address,
        "planner",
        progress=progress,
        valid=lambda r: isinstance(r.get("class"), int) and isinstance(r.get("methods_results"), dict),
    )
    return summarize(results, methods), results


def report(summary: dict, out) -> str:
    """Writes the figure and summary.json of a planner sweep in ``out``; returns its text."""
    import json
    from pathlib import Path

    from mog_drake.experiments import figures
    from mog_drake.experiments.sweep import reading_only
    from mog_drake.tables import format_table

    out = Path(out)
    if reading_only():  # --summary-only reads, never writes
        return (
            format_table(summary["rows"], COLUMNS)
            + f"\n\nresults: {out / 'results.jsonl'} (summary only: nothing written)"
        )
    png = figures.planner_figure(summary, out / "planner.png")
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return (
        format_table(summary["rows"], COLUMNS)
        + f"\n\nresults: {out / 'results.jsonl'}  summary: {out / 'summary.json'}  figure: {png}"
    )
