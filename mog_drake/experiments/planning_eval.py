"""Experiment 2 (paper Sec. 7.3): planning time and physics checks of GP vs its baselines.

Every method plans on the same seeded row scenes in the same run, each from a fresh verifier
(its first physics check pays the plant build, as a planner in a new scene would).
"""

from __future__ import annotations

import numpy as np

from mog_drake.experiments.conditions import row_tasks
from mog_drake.experiments.stats import mean_ci, proportion_ci
from mog_drake.experiments.sweep import check_params, run_sweep

PAPER_METHODS = ("gp", "rand-phys", "rank-phys", "rand-fil-phys")
#: The summary's columns, in the order tables print them.
COLUMNS = ["class", "method", "scenes", "time_s", "time_ci", "tested", "tested_ci", "found_pct", "gp_speedup"]


def planner_worker(task: dict) -> dict:
    from mog_drake.planning.planner import GraspPlanner, PlannerConfig
    from mog_drake.scenes import row_scene
    from mog_drake.sim.verifier import DrakeVerifier

    scene = row_scene(task["class"], np.random.default_rng(task["scene_seed"]))
    out = {}
    for m_index, method in enumerate(task["methods"]):
        cfg = PlannerConfig(
            method=method,
            max_physics=task.get("max_physics"),
            n_positions=task["n_positions"],
            n_orientations=task["n_orientations"],
        )
        planner = GraspPlanner(DrakeVerifier(), cfg)
        res = planner.plan(scene, scene.group, rng=np.random.default_rng([task["scene_seed"], m_index]))
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
    results = run_sweep(tasks, planner_worker, out_dir, jobs, ray_address, "planner", progress)
    return summarize(results, methods), results
