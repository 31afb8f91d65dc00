"""The physics check: the picking check against the reference check, pair by pair.

The reference is the check the picking planner used before its hold ended early
(`models/reference_check.yaml`: the whole 2.5 s hold unless every lifted object crept under
1 mm/s for 0.5 s, on a box table). Both run every pair of one set, alternately, on this
thread; CPU time is this thread's (`time.thread_time`), so run the bench alone.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from mog_drake.errors import MogError
from mog_drake.files import model_path

REFERENCE_FILE = model_path("reference_check.yaml")
ROW_CLASSES = range(2, 8)


def row_pairs(per_class: int, seed: int) -> list[dict]:
    """(scene, group, grasp) pairs on the paper's row scenes, classes 2-7: per seeded scene,
    the two best-ranked candidates that pass both necessary conditions (what the grasp
    planner simulates first)."""
    from mog_drake.geometry import evaluate_grasps, gen_grasp_cands, rank_grasp_cands
    from mog_drake.scenes import row_scene

    pairs = []
    for c in ROW_CLASSES:
        for k in range(per_class):
            scene = row_scene(c, np.random.default_rng([seed, c, k]))
            polys = scene.polygons()
            cands = gen_grasp_cands(polys, scene.group)
            if not len(cands):
                continue
            ev = evaluate_grasps(polys, scene.group, cands)
            for i in [i for i in rank_grasp_cands(ev) if ev.passed[i]][:2]:
                pairs.append(
                    {"kind": f"row {c}", "scene": scene, "group": list(scene.group), "grasp": cands[i]}
                )
    return pairs


def table_pairs(tables: int, seed: int) -> list[dict]:
    """Every physics check Alg. 1 makes (with the picking check) while it clears seeded
    33-object tables without the robot (`station.clear_table`, the scene seeds of ``eval
    picking --seed``), recorded."""
    from mog_drake.experiments.bench.station import clear_table
    from mog_drake.scenario import ClutteredScene, Scenario
    from mog_drake.station import scene_from_spec
    from mog_drake.systems.pick import make_planner

    sc = Scenario()
    planner = make_planner(sc)
    pairs, check = [], planner.verifier.check

    def recorded(scene, group, grasp):
        r = check(scene, group, grasp)
        if r.bodies:  # a simulation ran (not a grasp refused before it)
            pairs.append({"kind": "table", "scene": scene, "group": list(group), "grasp": np.array(grasp)})
        return r

    planner.verifier.check = recorded
    for k in range(tables):
        table_seed = seed * 1_000_000 + k
        for _ in clear_table(
            scene_from_spec(ClutteredScene(seed=table_seed)), planner, sc.planner, table_seed
        ):
            pass
    return pairs


def bench_verifier(per_class: int = 25, tables: int = 3, seed: int = 0, out=None, progress=None) -> dict:
    """The reference and the picking check on the same pairs (`row_pairs` and `table_pairs`):
    CPU per check of each, the agreement table, and every disagreement with the command that
    replays it (its scene written to ``out``)."""
    from mog_drake.scenario import Scenario, load_scenario
    from mog_drake.systems.pick import make_planner

    fast, ref = make_planner(Scenario()).verifier, make_planner(load_scenario(str(REFERENCE_FILE))).verifier
    pairs = row_pairs(per_class, seed) + table_pairs(tables, seed)
    if not pairs:
        raise MogError("no pair to check")
    rows, cpu = [], {"reference": [], "picking": []}
    for n, p in enumerate(pairs):
        res = {}
        for name, v in (("reference", ref), ("picking", fast)):
            c0 = time.thread_time()
            res[name] = v.check(p["scene"], p["group"], p["grasp"])
            cpu[name].append(time.thread_time() - c0)
        rows.append({**p, **res})
        if progress:
            progress(n + 1, len(pairs))
    return _summary(rows, cpu, out)


def _summary(rows: list[dict], cpu: dict, out) -> dict:
    a = np.array([r["reference"].success for r in rows])
    b = np.array([r["picking"].success for r in rows])
    both = a & b
    same_lifted = sum(
        sorted(r["reference"].lifted) == sorted(r["picking"].lifted) for r, s in zip(rows, both) if s
    )
    disagree = [r for r in rows if r["reference"].success != r["picking"].success]
    listed = []
    for k, r in enumerate(disagree):
        entry = {
            "kind": r["kind"],
            "group": r["group"],
            "grasp": [round(float(v), 6) for v in r["grasp"]],
            "reference": r["reference"].text(),
            "picking": r["picking"].text(),
        }
        if out is not None:
            path = Path(out) / f"disagreement_{k:02d}.yaml"
            path.parent.mkdir(parents=True, exist_ok=True)
            replace(r["scene"], group=tuple(r["group"])).save(path)
            x, y, th = (float(v) for v in r["grasp"])
            g = f"{x * 1e3:.4f} {y * 1e3:.4f} {math.degrees(th):.4f}"  # mm and degrees, as --grasp takes
            entry["replay"] = (
                f"mog-drake check {path} --grasp {g} --simulate [--scenario models/{REFERENCE_FILE.name}]"
            )
        listed.append(entry)
    timing = []
    for name, t in cpu.items():
        t = np.array(t)
        timing.append(
            {
                "check": name,
                "checks": len(t),
                "cpu_median_s": float(np.median(t)),
                "cpu_p90_s": float(np.percentile(t, 90)),
                "cpu_max_s": float(t.max()),
                "cpu_mean_s": float(t.mean()),
            }
        )
    ref_t, fast_t = timing
    return {
        "pairs": len(rows),
        "kinds": {k: sum(r["kind"] == k for r in rows) for k in dict.fromkeys(r["kind"] for r in rows)},
        "timing": timing,
        "median_ratio": ref_t["cpu_median_s"] / fast_t["cpu_median_s"],
        "mean_ratio": ref_t["cpu_mean_s"] / fast_t["cpu_mean_s"],
        "both_lift": int(both.sum()),
        "both_lift_same_objects": int(same_lifted),
        "both_fail": int((~a & ~b).sum()),
        "reference_only": int((a & ~b).sum()),
        "picking_only": int((~a & b).sum()),
        "agreement": float((a == b).mean()),
        "disagreements": listed,
    }


def verifier_text(doc: dict) -> str:
    from mog_drake.tables import format_table

    agree = [
        {
            "pairs": doc["pairs"],
            "both lift": doc["both_lift"],
            "same objects": doc["both_lift_same_objects"],
            "both fail": doc["both_fail"],
            "reference only": doc["reference_only"],
            "picking only": doc["picking_only"],
            "agreement": f"{100 * doc['agreement']:.1f} %",
        }
    ]
    kinds = ", ".join(f"{k}: {n}" for k, n in doc["kinds"].items())
    lines = [
        format_table(doc["timing"]),
        f"CPU per check, reference / picking: median {doc['median_ratio']:.2f}x, mean {doc['mean_ratio']:.2f}x",
        "",
        format_table(agree),
        f"pairs: {kinds}",
    ]
    for d in doc["disagreements"]:
        lines.append(f"  disagreement ({d['kind']}, group {d['group']}, grasp {d['grasp']}):")
        lines.append(f"    reference: {d['reference']}")
        lines.append(f"    picking:   {d['picking']}")
        if "replay" in d:
            lines.append(f"    replay:    {d['replay']}")
    return "\n".join(lines)
