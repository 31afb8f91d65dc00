"""Experiment 1 (paper Sec. 7.2): how many physics-negative grasps do the conditions predict?

For every collision-free candidate of every row scene: each condition's verdict and the physics
ground truth (close, lift under gravity). A candidate a condition rejects is a predicted
negative: a true negative if physics fails too, a false negative if physics lifts the group.
"""

from __future__ import annotations

import math
import time

import numpy as np

from mog_drake.experiments.stats import mean_ci
from mog_drake.experiments.sweep import check_params, run_sweep


def scene_seed(seed: int, n_class: int, index: int) -> int:
    """The integer seed of scene ``index`` of class ``n_class``; replay it with
    ``mog-drake scene generate --kind row --class C --seed SCENE_SEED``."""
    return seed * 1_000_000 + n_class * 10_000 + index


def row_tasks(
    classes, scenes_per_class: int, seed: int, n_positions: int = 70, n_orientations: int = 7
) -> list[dict]:
    return [
        {
            "key": f"c{c}-{k}",
            "class": int(c),
            "index": k,
            "scene_seed": scene_seed(seed, c, k),
            "n_positions": n_positions,
            "n_orientations": n_orientations,
        }
        for k in range(scenes_per_class)
        for c in classes
    ]


_VERIFIER = None


def _verifier():
    global _VERIFIER
    if _VERIFIER is None:
        from mog_drake.sim.verifier import row_verifier

        _VERIFIER = row_verifier()
    return _VERIFIER


def conditions_worker(task: dict) -> dict:
    """Ground truth for one scene: every collision-free candidate in physics."""
    from mog_drake.geometry import evaluate_grasps, gen_grasp_cands
    from mog_drake.scenes import row_scene

    t0 = time.perf_counter()
    scene = row_scene(task["class"], np.random.default_rng(task["scene_seed"]))
    polys = scene.polygons()
    cands = gen_grasp_cands(polys, scene.group, None, task["n_positions"], task["n_orientations"])
    ev = evaluate_grasps(polys, scene.group, cands)
    v = _verifier()
    rows = []
    for i, g in enumerate(cands):
        r = v.check(scene, scene.group, g)
        rows.append(
            [
                float(g[0]),
                float(g[1]),
                float(g[2]),
                bool(ev.diameter_ok[i]),
                bool(ev.area_ok[i]),
                bool(r.success),
                r.error,
            ]
        )
    return {
        **task,
        "n_candidates": len(cands),
        "h_fmin": ev.h_fmin,
        "columns": ["x", "y", "theta", "diameter_ok", "area_ok", "success", "error"],
        "candidates": rows,
        "wall_time": time.perf_counter() - t0,
    }


#: The summary's columns, in the order tables print them.
COLUMNS = [
    "class",
    "scenes",
    "candidates_per_scene",
    "negatives",
    "positives",
    "tn_area_pct",
    "tn_diameter_pct",
    "tn_either_pct",
    "tn_both_pct",
    "false_negatives",
    "tn_columns_pct",
    "false_negatives_columns",
    "ejected",
    "physics_errors",
]

# Counters per class: candidates, negatives, negatives rejected by area / by diameter / by
# either / by both, results with a physics fault, false negatives, results where an object was
# squeezed off the table (a failure, not a fault); with the frictional diameter condition
# (`GraspEvaluation.diameter_ok_columns`) in place of the paper's: negatives rejected by it or
# the area condition, and false negatives.
_N = 11


def is_fault(error: str) -> bool:
    """A check that did not run as intended (CPU budget, non-finite state, solver failure), as
    opposed to one whose objects were squeezed off the table, which is an outcome."""
    return bool(error) and not all("left the table" in part for part in error.split("; "))


def valid_row(rec: dict) -> bool:
    """A stored scene has what `summarize` reads: its class and a list of candidate rows of
    seven fields each."""
    rows = rec.get("candidates")
    return (
        isinstance(rec.get("class"), int)
        and isinstance(rows, list)
        and all(isinstance(r, list) and len(r) == 7 for r in rows)
    )


def summarize(results: list[dict]) -> dict:
    """Per-class and overall rows, plus every false negative with what replays it."""
    by_class: dict[int, list[dict]] = {}
    for r in results:
        by_class.setdefault(r["class"], []).append(r)
    rows, false_negatives = [], []
    totals = np.zeros(_N, dtype=int)
    for c in sorted(by_class):
        k = np.zeros(_N, dtype=int)
        for r in by_class[c]:
            columns = _columns_ok(r)
            for (x, y, th, d_ok, a_ok, success, err), c_ok in zip(r["candidates"], columns):
                k[0] += 1
                if is_fault(err):  # no ground truth: neither a negative nor a positive
                    k[6] += 1
                    continue
                k[8] += bool(err)
                if not success:
                    k[1] += 1
                    k[2] += not a_ok
                    k[3] += not d_ok
                    k[4] += (not a_ok) or (not d_ok)
                    k[5] += (not a_ok) and (not d_ok)
                    k[9] += (not a_ok) or (not c_ok)
                elif not (a_ok and d_ok):
                    k[7] += 1
                    k[10] += not (a_ok and c_ok)
                    false_negatives.append(
                        {
                            "class": c,
                            "scene_seed": r["scene_seed"],
                            "grasp": [x, y, th],
                            "diameter_ok": d_ok,
                            "area_ok": a_ok,
                            "n_positions": r.get("n_positions", 70),
                            "n_orientations": r.get("n_orientations", 7),
                            "replay": f"mog-drake scene generate --kind row --class {c} --seed {r['scene_seed']} "
                            f"-o fn.yaml && mog-drake check fn.yaml --grasp {x * 1e3:.4f} {y * 1e3:.4f} "
                            f"{math.degrees(th):.4f} --simulate --meshcat",
                        }
                    )
        totals += k
        rows.append(_row(str(c), k, [r["n_candidates"] for r in by_class[c]]))
    if results:
        rows.append(_row("all", totals, [r["n_candidates"] for r in results]))
    return {"rows": rows, "false_negatives": false_negatives}


def _columns_ok(r: dict) -> np.ndarray:
    """The frictional diameter condition's verdict on each recorded candidate of a scene's
    result (geometry only: the row scene is generated again from its seed)."""
    from mog_drake.geometry import evaluate_grasps
    from mog_drake.scenes import row_scene

    if not r["candidates"]:
        return np.zeros(0, dtype=bool)
    scene = row_scene(r["class"], np.random.default_rng(r["scene_seed"]))
    grasps = np.array([c[:3] for c in r["candidates"]], dtype=float)
    return evaluate_grasps(scene.polygons(), scene.group, grasps, columns=True).diameter_ok_columns


def explain_false_negatives(false_negatives: list[dict], verifier=None) -> list[dict]:
    """Replays each false negative and says why physics beat the condition.

    The conditions are necessary for a *frictionless* push-grasp. A group held with the jaws
    closer than h_fmin (the sum of the objects' minimum final diameters) cannot be a row of
    objects each pinched between the jaws: at least one is carried by friction (beside
    another, or pinched across a corner), which the conditions exclude by assumption.
    Adds h0, h_fmin, final_opening (mm), the replayed verdict and an ``explanation``."""
    from mog_drake.geometry import evaluate_grasps, gen_grasp_cands
    from mog_drake.scenes import row_scene

    if verifier is None:
        verifier = _verifier()
    out = []
    for fn in false_negatives:
        scene = row_scene(fn["class"], np.random.default_rng(fn["scene_seed"]))
        polys = scene.polygons()
        # The exact candidate, not its rounded record: a grasp held by friction can be
        # decided by a 1e-7 change.
        cands = gen_grasp_cands(polys, scene.group, None, fn["n_positions"], fn["n_orientations"])
        g = np.array(fn["grasp"], dtype=float)
        near = np.linalg.norm(cands - g, axis=1)
        if near.min() < 1e-5:
            g = cands[int(np.argmin(near))]
        ev = evaluate_grasps(polys, scene.group, g[None])
        r = verifier.check(scene, scene.group, g)
        h0, h_fmin, opening = 1e3 * float(ev.h0[0]), 1e3 * ev.h_fmin, 1e3 * r.final_opening
        thinnest = 1e3 * min(scene.shape(int(i)).d_fmin for i in scene.group)
        if not r.success:
            why = "not reproduced: the replay does not lift the group"
        elif opening < thinnest - 0.5:
            why = (
                f"carried outside the jaws: they closed to {opening:.1f} mm, narrower than the thinnest "
                f"group object ({thinnest:.1f} mm), so nothing was pinched between them"
            )
        elif opening < h_fmin - 0.5:
            why = (
                f"held by friction: the jaws stopped at {opening:.1f} mm, below h_fmin = {h_fmin:.1f} mm, "
                "which no frictionless grasp of the whole group can do"
            )
        elif not fn["area_ok"]:
            zero = [int(scene.group[i]) for i in np.flatnonzero(ev.areas[0] <= 1e-9)]
            why = f"object(s) {zero} had no area between the jaws (A_i = 0) and were carried by friction"
        else:
            why = f"unexplained: final opening {opening:.1f} mm >= h_fmin {h_fmin:.1f} mm"
        out.append(
            {
                **fn,
                "h0_mm": round(h0, 2),
                "h_fmin_mm": round(h_fmin, 2),
                "final_opening_mm": round(opening, 2),
                "replayed_success": bool(r.success),
                "explanation": why,
            }
        )
    return out


def _row(label: str, k: np.ndarray, n_cands: list[int]) -> dict:
    neg = max(int(k[1]), 1)
    cm, ch = mean_ci(n_cands)
    return {
        "class": label,
        "scenes": len(n_cands),
        "candidates_per_scene": cm,
        "candidates_ci": ch,
        "negatives": int(k[1]),
        "positives": int(k[0] - k[1] - k[6]),
        "tn_area_pct": 100 * k[2] / neg,
        "tn_diameter_pct": 100 * k[3] / neg,
        "tn_either_pct": 100 * k[4] / neg,
        "tn_both_pct": 100 * k[5] / neg,
        "false_negatives": int(k[7]),
        "tn_columns_pct": 100 * k[9] / neg,
        "false_negatives_columns": int(k[10]),
        "ejected": int(k[8]),
        "physics_errors": int(k[6]),
    }


def run(
    classes,
    scenes_per_class: int,
    seed: int,
    out_dir,
    *,
    jobs: int = 1,
    ray_address=None,
    progress: bool = True,
    n_positions: int = 70,
    n_orientations: int = 7,
) -> tuple[dict, list[dict]]:
    """Runs (or resumes) the sweep in ``out_dir``; returns (summary, per-scene results)."""
    check_params(
        out_dir,
        {
            "experiment": "conditions",
            "classes": list(classes),
            "seed": seed,
            "scenes_per_class": scenes_per_class,
            "n_positions": n_positions,
            "n_orientations": n_orientations,
        },
    )
    tasks = row_tasks(classes, scenes_per_class, seed, n_positions, n_orientations)
    results = run_sweep(
        tasks, conditions_worker, out_dir, jobs, ray_address, "conditions", progress=progress, valid=valid_row
    )
    summary = summarize(results)
    summary["false_negatives"] = explain_false_negatives(summary["false_negatives"])
    return summary, results


def report(summary: dict, out) -> str:
    """Writes the figure and summary.json of a conditions sweep in ``out``; returns its text."""
    import json
    from pathlib import Path

    from mog_drake.experiments import figures
    from mog_drake.experiments.sweep import reading_only
    from mog_drake.tables import format_table

    out = Path(out)
    text = format_table(summary["rows"], COLUMNS)
    fns = summary["false_negatives"]
    text += f"\n\nfalse negatives: {len(fns)}" + "".join(
        f"\n  class {f['class']}, scene {f['scene_seed']}: {f['explanation']}\n    {f['replay']}"
        for f in fns[:20]
    )
    if len(fns) > 20:
        text += f"\n  ... {len(fns) - 20} more in {out / 'summary.json'}"
    if reading_only():  # --summary-only reads, never writes
        return text + f"\n\nresults: {out / 'results.jsonl'} (summary only: nothing written)"
    png = figures.conditions_figure(summary, out / "conditions.png")
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return text + f"\n\nresults: {out / 'results.jsonl'}  summary: {out / 'summary.json'}  figure: {png}"
