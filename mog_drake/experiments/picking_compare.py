"""Pairing picking sweeps: two sweeps' runs on the tables both ran (`compare`), two modes of
one sweep (`compare_modes`), and the refusal, before a sweep runs, to pair sweeps of other
tables (`check_comparable`)."""

from __future__ import annotations

from pathlib import Path

from mog_drake.experiments.machine import speed_gap
from mog_drake.experiments.stats import mean_ci
from mog_drake.experiments.sweep import read_params


def transit_drops(runs: list[dict]) -> dict:
    """The runs' objects dropped in transit: lifted (in the air as the arm left for the bin)
    but not in the bin when the attempt ended (`dropped_in_transit`). {"drop_attempts":
    attempts that dropped some, "dropped": objects, "attempts": all attempts, and of the
    failed attempts (none in the bin) "missed": those that lifted nothing, "lost": those that
    dropped all they lifted}."""
    from mog_drake.systems.pick_run import dropped_in_transit

    out = {"drop_attempts": 0, "dropped": 0, "attempts": 0, "missed": 0, "lost": 0}
    for r in runs:
        for a in r.get("attempts", ()):
            out["attempts"] += 1
            lost = dropped_in_transit(a)
            if lost > 0:
                out["drop_attempts"] += 1
                out["dropped"] += lost
            if a.get("picked") == 0:
                out["lost" if lost > 0 else "missed"] += 1
    return out


#: Per-table numbers ``compare`` pairs, with the factor that turns them into the table's units.
PAIRED = {
    "success_rate": 100.0,
    "picked_pct": 1.0,
    "objects_per_success": 1.0,
    "pph": 1.0,
    "attempts": 1.0,
    "robot_time_s": 1.0,
    "planning_time_s": 1.0,
    "cycle_time_s": 1.0,
    "wait_perception_s": 1.0,
    "wait_planning_s": 1.0,
}


COMPARE_COLUMNS = ["mode", "metric", "tables", "a", "b", "b_minus_a", "ci"]


def tables_of(params: dict) -> dict:
    """What decides a picking sweep's tables, from its parameters (sweep.json): the seed, the
    objects and the time limit (each run's `task_scenario` sets the scene from them, on the
    default isrr33 inventory), and its scenario's table (read alone: a sweep made with
    settings since removed still names its tables)."""
    import yaml

    from mog_drake.scenario import Scenario

    try:
        doc = yaml.safe_load(params.get("scenario") or "") or {}
    except yaml.YAMLError:
        doc = {}
    table = doc.get("table", Scenario().table) if isinstance(doc, dict) else Scenario().table
    return {
        "seed": params.get("seed"),
        "objects": params.get("objects"),
        "time_limit": params.get("time_limit"),
        "table": [float(v) for v in table],
    }


def check_comparable(compare_dir, params: dict) -> None:
    """Refuses, before a sweep runs, to pair it with the sweep in ``compare_dir`` unless both
    ran the same tables (`tables_of`): the one line names the first difference."""

    from mog_drake.errors import MogError

    where = Path(compare_dir) / "sweep.json"
    if not where.exists():
        raise MogError(f"--compare: {where} does not exist (give a picking sweep's --out folder)")
    try:
        other = read_params(compare_dir)
    except MogError as e:
        raise MogError(f"--compare: {e}") from None
    if other.get("experiment") != "picking":
        raise MogError(f"--compare: {where} is not a picking sweep")
    results = Path(compare_dir) / "results.jsonl"
    if results.exists() and not results.is_file():  # read once this sweep has run: refused now
        raise MogError(f"--compare: {results}: not a regular file, not a sweep's results (JSON lines)")
    a, b = tables_of(other), tables_of(params)
    for key in a:
        if a[key] != b[key]:
            raise MogError(
                f"--compare: {compare_dir} ran other tables ({key} {_short(a[key])}, here {_short(b[key])})"
            )


def _short(value, n: int = 80) -> str:
    text = str(value)
    return text if len(text) <= n else text[: n - 3] + "..."


def compare(results_a: list[dict], results_b: list[dict]) -> dict:
    """Sweep B against sweep A on the tables both ran (same key and table seed): per mode and
    metric, both means and the mean paired difference B - A with its 95 % t interval (the
    tables are the pairs, so table-to-table spread cancels). Also each side's transit drops
    over those tables, and ``machines``: why their runs' timings do not pair, or ""
    (`machine.speed_gap`). Raises ``MogError`` when the two sweeps share no table."""
    from mog_drake.errors import MogError

    a = {r["key"]: r for r in results_a}
    b = {r["key"]: r for r in results_b}
    common = [k for k in a if k in b and a[k].get("scene_seed") == b[k].get("scene_seed")]
    if not common:
        raise MogError("the two picking sweeps share no table (same key and table seed): nothing to pair")
    rows, drops = [], {}
    for m in dict.fromkeys(a[k]["mode"] for k in common):
        keys = [k for k in common if a[k]["mode"] == m]
        for metric, scale in PAIRED.items():
            pairs = [
                (a[k]["summary"][metric] * scale, b[k]["summary"][metric] * scale)
                for k in keys
                if metric in a[k]["summary"]
                and metric in b[k]["summary"]
                and a[k]["summary"][metric] == a[k]["summary"][metric]
                and b[k]["summary"][metric] == b[k]["summary"][metric]
            ]
            if not pairs:  # a metric one of the sweeps did not record
                continue
            diff, ci = mean_ci([y - x for x, y in pairs])
            rows.append(
                {
                    "mode": m,
                    "metric": metric,
                    "tables": len(pairs),
                    "a": mean_ci([x for x, _ in pairs])[0],
                    "b": mean_ci([y for _, y in pairs])[0],
                    "b_minus_a": diff,
                    "ci": ci,
                }
            )
        drops[m] = {"a": transit_drops([a[k] for k in keys]), "b": transit_drops([b[k] for k in keys])}
    machines = speed_gap([a[k] for k in common], [b[k] for k in common])
    return {"rows": rows, "transit_drops": drops, "tables": len(common), "machines": machines}


def compare_modes(results: list[dict], a_mode: str, b_mode: str) -> dict:
    """Mode B against mode A on the tables of one sweep that ran both (`compare`'s rows,
    labelled "B vs A"), and table by table: PPH and objects per successful grasp of each,
    the PPH ratio B / A, B's wait for compute as a share of its robot time, and the PPH ratio
    had neither arm waited (``robot_pph_ratio``: objects in the bin per second of robot time,
    B / A), the ratio's ceiling from the motions alone."""

    def side(mode):
        label = f"{b_mode} vs {a_mode}"
        return [{**r, "key": f"s{r['scene']}", "mode": label} for r in results if r["mode"] == mode]

    a, b = side(a_mode), side(b_mode)
    paired = compare(a, b)
    by_a = {r["key"]: r["summary"] for r in a}
    tables = []
    for r in sorted(b, key=lambda r: r["scene"]):
        sa, sb = by_a.get(r["key"]), r["summary"]
        if sa is None:
            continue
        tables.append(
            {
                "table": r["scene"],
                f"pph_{a_mode}": sa["pph"],
                f"pph_{b_mode}": sb["pph"],
                f"pph_no_wait_{b_mode}": _robot_pph(sb),  # its ceiling: had the arm never waited
                "pph_ratio": sb["pph"] / sa["pph"] if sa["pph"] else float("nan"),
                f"wait_pct_{b_mode}": wait_pct(sb),
                "robot_pph_ratio": _robot_pph(sb) / _robot_pph(sa) if _robot_pph(sa) else float("nan"),
                f"per_grasp_{a_mode}": sa["objects_per_success"],
                f"per_grasp_{b_mode}": sb["objects_per_success"],
                f"picked_{b_mode}": sb["picked_pct"],
                "pushes": sb.get("pushes", 0),
                # B's grasps of one object, by why no push set up more (`lone_reason`).
                **{f"lone_{k.replace(' ', '_')}": n for k, n in lone_reasons([r]).items()},
            }
        )
    return {**paired, "per_table": tables, "robot_time": robot_time_split(a, b)}


def robot_time_split(a: list[dict], b: list[dict]) -> dict:
    """Where mode B's robot time goes against mode A's, on the tables both ran: the ratio of
    their robot times (A / B, the PPH ratio had neither arm waited: both clear the table),
    the same with B's pushes taking no time, the robot time per grasp of each (B's without
    its pushes), and per push with how far its object moved (mm)."""
    by_a = {r["key"]: r for r in a}
    pairs = [(by_a[r["key"]], r) for r in b if r["key"] in by_a]
    pairs = [
        (ra, rb)
        for ra, rb in pairs
        if ra["summary"]["robot_time_s"] > 0 and rb["summary"]["robot_time_s"] > 0
    ]
    if not pairs:
        return {}
    sa = [ra["summary"] for ra, _ in pairs]
    sb = [rb["summary"] for _, rb in pairs]
    pushes = [p for _, rb in pairs for p in rb.get("pushes", ())]
    push_s = sum(s.get("push_time_s", 0.0) for s in sb)
    return {
        "tables": len(pairs),
        "ratio": mean_ci([x["robot_time_s"] / y["robot_time_s"] for x, y in zip(sa, sb)])[0],
        "ratio_pushes_free": mean_ci(
            [x["robot_time_s"] / (y["robot_time_s"] - y.get("push_time_s", 0.0)) for x, y in zip(sa, sb)]
        )[0],
        "grasp_s_a": sum(x["robot_time_s"] for x in sa) / max(sum(x["attempts"] for x in sa), 1),
        "grasp_s_b": (sum(y["robot_time_s"] for y in sb) - push_s) / max(sum(y["attempts"] for y in sb), 1),
        "pushes": len(pushes),
        "push_s": push_s / len(pushes) if pushes else float("nan"),
        "push_mm": 1e3 * sum(p["push"]["distance"] for p in pushes) / len(pushes) if pushes else float("nan"),
    }


def robot_time_text(doc: dict, a_mode: str, b_mode: str) -> str:
    """`robot_time_split` as a line; empty where no table ran both."""
    if not doc:
        return ""
    return (
        f"{b_mode} against {a_mode}, robot time alone (had neither arm waited), {doc['tables']} tables: "
        f"{doc['ratio']:.2f}x; with {b_mode}'s pushes taking no time {doc['ratio_pushes_free']:.2f}x. "
        f"A grasp took {doc['grasp_s_a']:.2f} s ({a_mode}) and {doc['grasp_s_b']:.2f} s ({b_mode}); "
        f"a push {doc['push_s']:.2f} s ({doc['pushes']} pushes, the object moved {doc['push_mm']:.0f} mm on average)"
    )


def lone_reasons(runs: list[dict]) -> dict:
    """The push-mog runs' grasps of one object by why no push set up more: {reason: n},
    every reason of `LONE_REASONS`; empty where none is recorded (other modes, and runs from
    before it was)."""
    from mog_drake.planning.pushing import LONE_REASONS

    runs = [r for r in runs if r["mode"].startswith("push-mog") and "lone_grasps" in r["summary"]]
    if not runs:
        return {}
    found = [a["lone"] for r in runs for a in r.get("attempts", ()) if a.get("lone")]
    return {k: found.count(k) for k in LONE_REASONS}


def wait_pct(summary: dict) -> float:
    """The arm's wait for compute as a share of its robot time (%); nan if not recorded."""
    try:
        return 100.0 * (summary["wait_perception_s"] + summary["wait_planning_s"]) / summary["robot_time_s"]
    except (KeyError, ZeroDivisionError):
        return float("nan")


def _robot_pph(summary: dict) -> float:
    """Objects in the bin per hour of robot time: the PPH had the arm never waited; nan if
    not recorded."""
    try:
        return summary["pph"] * summary["cycle_time_s"] / summary["robot_time_s"]
    except (KeyError, ZeroDivisionError):
        return float("nan")


def compare_text(doc: dict) -> str:
    from mog_drake.tables import format_table

    text = format_table(doc["rows"], COMPARE_COLUMNS, {"b_minus_a": "B - A", "ci": "+-95 %"})
    for m, sides in doc["transit_drops"].items():
        text += f"\n{m}: objects dropped in transit: " + "; ".join(
            f"{side.upper()} {d['dropped']} ({d['drop_attempts']} of {d['attempts']} attempts)"
            for side, d in sides.items()
        )
    return text
