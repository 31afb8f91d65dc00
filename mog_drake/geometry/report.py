"""One scene's necessary conditions as text and documents: a grasp's figures (`check`) and
every candidate ranked (`candidates`). No Drake import."""

from __future__ import annotations

import math

from mog_drake.geometry.candidates import ranked_candidates
from mog_drake.geometry.conditions import evaluate_grasps
from mog_drake.geometry.gripper import GripperGeometry
from mog_drake.tables import format_table


def _mm(v) -> str:
    return "-" if v is None else f"{v * 1e3:.2f} mm"


def record_lines(rec: dict) -> list[str]:
    """A candidate's `GraspEvaluation.record` as lines of text (mm, mm^2, deg)."""
    g = rec["grasp"]
    lines = [
        f"grasp      x={g[0] * 1e3:.2f} mm  y={g[1] * 1e3:.2f} mm  theta={math.degrees(g[2]):.2f} deg",
        f"h0         {rec['h0'] * 1e3:.2f} mm   (b_l {_mm(rec['b_l'])}, b_r {_mm(rec['b_r'])})",
        f"h_fmin     {rec['h_fmin'] * 1e3:.2f} mm",
        "areas      " + ", ".join(f"A_{k}={v * 1e6:.1f} mm^2" for k, v in rec["areas"].items()),
        f"diameter_ok {rec['diameter_ok']}   area_ok {rec['area_ok']}   collision_free {rec['collision_free']}",
        f"verdict    {rec['verdict']}",
    ]
    if rec["other_objects_in_S"]:
        lines.append(f"also in S  {rec['other_objects_in_S']} (not in the group)")
    return lines


def candidate_rows(records: list[dict]) -> list[dict]:
    """Ranked candidates' records as table rows (mm, mm^2, deg)."""
    return [
        {
            "rank": r["rank"],
            "x_mm": r["grasp"][0] * 1e3,
            "y_mm": r["grasp"][1] * 1e3,
            "theta_deg": math.degrees(r["grasp"][2]),
            "h0_mm": r["h0"] * 1e3,
            "A_T_mm2": r["area_total"] * 1e6,
            "min_A_i_mm2": min(r["areas"].values()) * 1e6,
            "verdict": r["verdict"],
        }
        for r in records
    ]


def check_report(scene, group, source: str, grasp, gripper: GripperGeometry) -> tuple[dict, list[str]]:
    """The necessary conditions for ``grasp`` on ``group`` (found from ``source``)."""
    rec = evaluate_grasps(scene.polygons(), group, grasp[None, :], gripper).record(0)
    lines = record_lines(rec)
    lines.insert(1, f"group      {list(group)} ({source})")
    return {"group": list(group), "group_source": source, **rec}, lines


def candidates_report(
    scene,
    group,
    source: str,
    gripper: GripperGeometry,
    positions: int,
    orientations: int,
    *,
    limit: int,
    all_rows: bool,
) -> tuple[dict, str]:
    """Every candidate for ``group``, ranked by A_T, with its figures and verdict; the text
    table shows the first ``limit`` (colliding ones only with ``all_rows``)."""
    ev, order = ranked_candidates(scene.polygons(), group, gripper, positions, orientations)
    recs = [{**ev.record(int(i)), "rank": rank} for rank, i in enumerate(order)]
    counts = {v: sum(r["verdict"] == v for r in recs) for v in ("collision", "diameter", "area", "passed")}
    doc = {
        "group": list(group),
        "group_source": source,
        "h_fmin": ev.h_fmin,
        "counts": counts,
        "candidates": recs,
    }
    shown = [r for r in recs if r["verdict"] != "collision" or all_rows][:limit]
    text = (
        f"group {list(group)} ({source}); h_fmin = {ev.h_fmin * 1e3:.2f} mm; {len(recs)} candidates: "
        + ", ".join(f"{k} {v}" for k, v in counts.items())
        + "\n"
        + format_table(candidate_rows(shown))
    )
    return doc, text
