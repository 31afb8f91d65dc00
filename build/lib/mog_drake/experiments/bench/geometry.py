"""The geometry's speed: the necessary conditions and the candidate filter, batched."""

from __future__ import annotations

import time
from functools import partial

import numpy as np

from mog_drake.geometry import GripperGeometry, evaluate_grasps, gen_grasp_cands, rank_grasp_cands
from mog_drake.scenes import row_scene


def _timed(fn, repeats: int):
    best = []
    out = None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        best.append(time.perf_counter() - t)
    return float(np.median(best)), out


def _filter_rank(polys, group, cands, gripper, columns: bool = False):
    ev = evaluate_grasps(polys, group, cands, gripper, columns=columns)
    order = rank_grasp_cands(ev)
    return order[(ev.passed_columns if columns else ev.passed)[order]]


def bench_geometry(
    scenes_per_class: int = 20,
    seed: int = 0,
    repeats: int = 5,
    classes=range(2, 8),
    gripper: GripperGeometry | None = None,
) -> list[dict]:
    """Median time per scene of candidate generation (Np x Ntheta grasps + jaw collision
    rejection), of filtering + ranking (h0, A_i, both conditions, sort by A_T), the same with
    the frictional diameter condition, and in total, for the paper's row classes. Each scene's figure is the median of ``repeats`` runs."""
    gripper = gripper or GripperGeometry()
    rows = []
    for c in classes:
        gen_t, fil_t, col_t, n_cands = [], [], [], []
        for k in range(scenes_per_class):
            scene = row_scene(c, np.random.default_rng([seed, c, k]))
            polys = scene.polygons()
            tg, cands = _timed(partial(gen_grasp_cands, polys, scene.group, gripper), repeats)
            tf, _ = _timed(partial(_filter_rank, polys, scene.group, cands, gripper), repeats)
            tc, _ = _timed(partial(_filter_rank, polys, scene.group, cands, gripper, True), repeats)
            gen_t.append(tg)
            fil_t.append(tf)
            col_t.append(tc)
            n_cands.append(len(cands))
        tot = np.array(gen_t) + np.array(fil_t)
        rows.append(
            {
                "objects": c,
                "scenes": scenes_per_class,
                "candidates": float(np.mean(n_cands)),
                "generate_ms": 1e3 * float(np.median(gen_t)),
                "filter_rank_ms": 1e3 * float(np.median(fil_t)),
                # the same with the frictional diameter condition (planner.grasp.diameter_condition)
                "filter_rank_columns_ms": 1e3 * float(np.median(col_t)),
                "total_ms": 1e3 * float(np.median(tot)),
                "total_max_ms": 1e3 * float(np.max(tot)),
            }
        )
    return rows
