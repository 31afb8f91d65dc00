"""Sweeps' results as pandas DataFrames, for notebooks (pandas: the `notebooks` extra).

* `runs`: one row per run (a table in a mode) with its summary;
* `attempts`: one row per grasp attempt, with its outcome and the cause of a failure;
* `paired`: two sweeps of the same tables, per measure their paired difference;
* `study`: the uncertainty study's levels, one row per level and mode;
* `landings`: where the open plates came down, per sweep and mode.
"""

from __future__ import annotations

from pathlib import Path

# Outcomes of an attempt, as `attempts` names them.
OUTCOMES = (
    "taken",
    "part taken",
    "dropped on the way",
    "stopped on the way down",
    "closed on nothing",
    "lifted nothing",
)
# A jaw opening after the close below this (m): the jaws met with nothing between them.
EMPTY_JAWS = 0.002


def _pd():
    try:
        import pandas as pd
    except ImportError:
        from mog_drake.errors import MogError

        raise MogError("DataFrames need pandas: pip install 'mog_drake[notebooks]'") from None
    return pd


def _records(folder) -> list[dict]:
    """A sweep folder's runs; from {mode: folder}, each mode's runs from its own sweep."""
    from mog_drake.experiments.sweep import load_results

    if isinstance(folder, dict):
        return [r for m, f in folder.items() for r in _records(f) if r["mode"] == m]
    return list(load_results(Path(folder) / "results.jsonl", repair=False).values())


def runs(folder):
    """One row per run of a picking sweep: its table, mode and summary."""
    pd = _pd()
    rows = [
        {"key": r["key"], "table": r["scene"], "mode": r["mode"], **r["summary"]} for r in _records(folder)
    ]
    return pd.DataFrame(rows).sort_values(["mode", "table"]).reset_index(drop=True)


def outcome(a: dict) -> str:
    """An attempt's outcome (OUTCOMES): everything it meant to take in the bin, part of it,
    lifted and lost on the way, the jaws closed with nothing between them (the objects were
    not where perception put them, or were pushed away), or nothing lifted though the jaws
    held something (it slipped out at the lift); or the guarded descent stopped on an object
    before the jaws closed."""
    picked, expected = a.get("picked") or 0, len(a.get("expected") or a.get("group") or ())
    carried = len(a.get("carried") or ())
    if picked >= max(expected, 1):
        return "taken"
    if picked > 0:
        return "part taken"
    if carried > 0:
        return "dropped on the way"
    if a.get("stopped"):
        return "stopped on the way down"
    if (a.get("held_width") or 0.0) < EMPTY_JAWS:
        return "closed on nothing"
    return "lifted nothing"


def attempts(folder):
    """One row per grasp attempt of a picking sweep (a folder, or {mode: folder}): when
    (simulated s), the group's size and shapes, what it meant to take, what it took, its
    planning time, its outcome, and how many objects its open jaws came down on and how far
    onto the deepest (mm; ground truth; None in sweeps from before it was recorded), and how
    many objects lying in view its scene had nothing for (``unseen``; 0 also in sweeps from
    before v54, which did not record it), and whether its decision was a last resort
    (``last_resort``: no grasp within the planner's cap)."""
    pd = _pd()
    rows = []
    for r in _records(folder):
        for k, a in enumerate(r["attempts"], start=1):
            rows.append(
                {
                    "key": r["key"],
                    "table": r["scene"],
                    "mode": r["mode"],
                    "attempt": k,
                    "start_s": a["start"],
                    "end_s": a.get("end"),
                    "objects": len(a["group"]),
                    "shapes": " + ".join(a.get("shapes") or ()),
                    "expected": len(a.get("expected") or a["group"]),
                    "picked": a.get("picked"),
                    "planning_s": a.get("planning_time"),
                    "held_width_mm": 1e3 * (a.get("held_width") or 0.0),
                    "outcome": outcome(a),
                    "jaws_on": None if a.get("jaws_on") is None else len(a["jaws_on"]),
                    "landed_mm": None
                    if a.get("jaws_on") is None
                    else max(a["jaws_on"].values(), default=0.0),
                    "approach_force": a.get("approach_force"),
                    "unseen": len(a.get("unseen") or ()),
                    "last_resort": bool(a.get("last_resort")),
                }
            )
    return pd.DataFrame(rows)


def paired(folder_a, folder_b):
    """Per measure, B - A on the tables both sweeps ran (each mode): the mean difference and
    its 95 % interval (`picking_compare.compare`)."""
    from mog_drake.experiments.picking_compare import compare

    pd = _pd()
    doc = compare(_records(folder_a), _records(folder_b))
    return pd.DataFrame(doc["rows"])


def study(levels: dict, common: bool = True):
    """The uncertainty study: {level: sweep folder, or {mode: sweep folder} to take each mode
    from its own sweep} -> one row per level and mode (success %, picked %, objects per
    successful grasp, PPH, with their 95 % intervals). ``common``: each
    mode on the tables every level ran it on, so that the levels differ in their uncertainty
    alone (a table's own draws move its success by tens of points); else each level on all
    its tables."""
    from mog_drake.experiments.picking_eval import summarize

    pd = _pd()
    runs = {level: _records(folder) for level, folder in levels.items()}
    runs = {level: res for level, res in runs.items() if res}
    shared = {}
    if common and runs:
        for m in {r["mode"] for res in runs.values() for r in res}:
            tables = [{r["scene"] for r in res if r["mode"] == m} for res in runs.values()]
            shared[m] = set.intersection(*tables)
    rows = []
    for level, res in runs.items():
        if common:
            res = [r for r in res if r["scene"] in shared[r["mode"]]]
        modes = sorted({r["mode"] for r in res})
        if not modes:
            continue
        for row in summarize(res, modes)["rows"]:
            rows.append({"level": level, **row})
    return pd.DataFrame(rows)


# A plate that comes down at least this far onto an object counts as landing on it (mm); a real
# arm stops at the TCP force limit of its safety configuration: 150 N here is a setting, not a
# measurement (pass another).
LANDED_MM, STOP_N = 1.0, 150.0


def landings(sweeps: dict, landed_mm: float = LANDED_MM, stop_n: float = STOP_N):
    """Where the open plates came down (ground truth, from sweeps that recorded it):
    {name: sweep folder} -> one row per sweep and mode: attempts, the share whose plates came
    down ``landed_mm`` or more onto an object, the success of those and of all, the success had
    every such attempt failed (as on a rigid object, docs/physics.md), and the share whose open
    fingers pressed an object with ``stop_n`` or more (a real arm would have stopped)."""
    pd = _pd()
    rows = []
    for name, folder in sweeps.items():
        att = attempts(folder)
        att = att[att.jaws_on.notna()] if len(att) else att
        for mode, g in att.groupby("mode") if len(att) else ():
            landed = g.landed_mm >= landed_mm
            taken = g.picked.fillna(0) > 0
            rows.append(
                {
                    "sweep": name,
                    "mode": mode,
                    "attempts": len(g),
                    "landed_pct": 100 * landed.mean(),
                    "success_if_landed_pct": 100 * taken[landed].mean() if landed.any() else float("nan"),
                    "success_pct": 100 * taken.mean(),
                    "success_if_landings_fail_pct": 100 * (taken & ~landed).mean(),
                    "pressed_to_stop_pct": 100 * (g.approach_force >= stop_n).mean(),
                }
            )
    return pd.DataFrame(rows)
