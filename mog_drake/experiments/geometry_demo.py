"""The planner's geometry on two example scenes (a row and a cluttered table): the candidates,
their verdicts and the best-ranked ones, as a table and a picture each."""

import math
from pathlib import Path

import numpy as np

from mog_drake import plotting
from mog_drake.geometry import GripperGeometry, ranked_candidates
from mog_drake.scenes import cluttered_scene, row_scene
from mog_drake.tables import format_table


def _first_passing(scene, gripper):
    """(group, source, evaluation, ranking) of the scene's own group, or else of the first of
    Alg. 1's groups, largest first, with a candidate that passes both conditions (the group
    the planner would go on to check in physics; the largest when none has one)."""
    from mog_drake.geometry import create_obj_groups, rank_obj_groups

    polys = scene.polygons()
    if scene.group is not None:
        groups, source = [tuple(scene.group)], "scene"
    else:
        groups, source = (
            rank_obj_groups(create_obj_groups(polys.centers), polys.d_fmin, gripper.w_g),
            "largest passing",
        )
    first = None
    for group in groups:
        ev, order = ranked_candidates(polys, group, gripper)
        first = first or (group, ev, order)
        if ev.passed.any():
            return group, source, ev, order
    return first[0], "largest", first[1], first[2]


def geometry_demo(out, seed: int = 2) -> tuple[dict, str]:
    """Writes each scene's YAML and picture to ``out``; returns (document, text)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    gripper = GripperGeometry()
    docs, text = [], ""
    for name, scene in (
        ("row4", row_scene(4, np.random.default_rng(seed))),
        ("cluttered", cluttered_scene(np.random.default_rng(seed))),
    ):
        scene.save(out / f"{name}.yaml")
        group, source, ev, order = _first_passing(scene, gripper)
        png = plotting.save(
            plotting.scene_figure(
                scene,
                group,
                ev,
                order,
                gripper=gripper,
                title=f"{name}: group {list(group)} ({source}), h_fmin {ev.h_fmin * 1e3:.1f} mm",
            ),
            out / f"{name}.png",
        )
        top = [int(i) for i in order if ev.passed[i]][:5]
        rows = [
            {
                "rank": k,
                "x_mm": ev.grasps[i, 0] * 1e3,
                "y_mm": ev.grasps[i, 1] * 1e3,
                "theta_deg": math.degrees(ev.grasps[i, 2]),
                "h0_mm": ev.h0[i] * 1e3,
                "A_T_mm2": ev.area_total[i] * 1e6,
            }
            for k, i in enumerate(top)
        ]
        counts = {v: int(sum(ev.verdict(i) == v for i in range(len(ev)))) for v in plotting.VERDICT_COLORS}
        text += (
            f"\n{name}: {len(scene)} objects, group {list(group)} ({source}), h_fmin {ev.h_fmin * 1e3:.2f} mm\n"
            + "candidates: "
            + ", ".join(f"{k} {v}" for k, v in counts.items())
            + "\n"
            + (format_table(rows) if rows else "(no candidate passes both conditions)")
            + f"\npicture: {png}\n"
        )
        docs.append({"name": name, "group": list(group), "counts": counts, "png": str(png)})
    return {"scenes": docs}, text
