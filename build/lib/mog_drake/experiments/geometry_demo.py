"""The planner's geometry on two example scenes (a row and a cluttered table): the candidates,
their verdicts and the best-ranked ones, as a table and a picture each."""

import math
from pathlib import Path

import numpy as np

from mog_drake import plotting
from mog_drake.geometry import GripperGeometry, ranked_candidates
from mog_drake.scenes import cluttered_scene, row_scene
from mog_drake.tables import format_table


def geometry_demo(out, seed: int = 0) -> tuple[dict, str]:
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
        group, source = scene.default_group(gripper.w_g)
        ev, order = ranked_candidates(scene.polygons(), group, gripper)
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
