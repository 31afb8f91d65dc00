"""Benchmarks that print tables. Speed is shown here, never asserted in tests.

`run(what, ...)` returns (doc, text) for `mog-drake bench WHAT`:

* geometry: the conditions and the candidate filter (`bench.geometry`)
* verifier: the picking check against the reference check, pair by pair (`bench.physics`)
* perception, station, replanning, rest: rendered tables, the station's step (and where a
  pick run's CPU goes, `bench.cell`), replanning, objects at rest on the station's table
  (`bench.station`)
* landing: an open plate coming down on an object in the station (`bench.landing`)
"""

from __future__ import annotations

import statistics

from mog_drake.tables import format_table

# Each benchmark and what it measures (`mog-drake bench --help`).
BENCHES = {
    "geometry": "the conditions and the candidate filter, per scene",
    "verifier": "the picking check against the reference check, pair by pair",
    "perception": "perception's accuracy and time per image on rendered tables",
    "station": "the simulated station's CPU per simulated second, and where it goes",
    "replanning": "the planner's CPU on whole tables, large groups capped and not",
    "rest": "whether every shape lies still on the station's table",
    "calibration": "the camera's pose from a rendered board against the drawn true pose",
    "large": "time and memory of the station, perception and the first decision, 33 to 300 objects",
    "landing": "what the station does when an open plate comes down on an object",
}


def perception_summary(rows: list[dict]) -> str:
    """One line per depth noise level: what was found, invented and missed, the worst errors
    and the time per image."""
    lines = []
    for level in dict.fromkeys(r["noise"] for r in rows):
        rs = [r for r in rows if r["noise"] == level]
        t = [r["time_s"] for r in rs]
        lines.append(
            f"noise {level:g}x: found {sum(r['found'] for r in rs)}, missed {sum(r['missed'] for r in rs)}, "
            f"extra {sum(r['extra'] for r in rs)}, unrecognised {sum(r['unrecognised'] for r in rs)}, "
            f"seen with a share of their pose error {sum(r['parted'] for r in rs)} of {sum(r['objects'] for r in rs)}; "
            f"worst position {max(r['pos_max_mm'] for r in rs):.2f} mm (each fit apart from the shift all "
            f"share: worst {max(r['fit_max_mm'] for r in rs):.2f} mm), worst yaw "
            f"{max(r['yaw_max_deg'] for r in rs):.2f} deg; shared shift {statistics.median(r['shift_mm'] for r in rs):.2f} mm "
            f"(median table); per image median {statistics.median(t):.3f} s, worst {max(t):.3f} s "
            f"(CPU median {statistics.median(r['cpu_s'] for r in rs):.3f} s)"
        )
    return "\n".join(lines)


def run(
    what: str,
    scenes: int = 20,
    seed: int = 0,
    toppled: int = 0,
    progress: bool = True,
    tables: int = 3,
    *,
    out=None,
    scenario: str | None = None,
    mode: str | None = None,
    noise_levels=None,
    camera_height: float | None = None,
    calibrate: bool = False,
) -> tuple[dict, str]:
    """Runs one benchmark; returns its document and its table as text."""
    from mog_drake.progress import Progress

    if what == "geometry":
        from mog_drake.experiments.bench.geometry import bench_geometry

        rows = bench_geometry(scenes, seed)
    elif what == "verifier":
        from mog_drake.experiments.bench.physics import bench_verifier, verifier_text

        bar = Progress(1, what, enabled=progress)
        doc = bench_verifier(scenes, tables, seed, out, progress=bar)
        bar.close()
        return doc, verifier_text(doc)
    elif what == "perception":
        from mog_drake.experiments.bench.station import bench_perception

        rows = bench_perception(
            scenes,
            seed,
            toppled,
            scenario=scenario,
            noise_levels=noise_levels,
            camera_height=camera_height,
            calibrate=calibrate,
        )
        return {what: rows}, format_table(rows) + "\n" + perception_summary(rows)
    elif what == "station":
        from mog_drake.experiments.bench.cell import bench_cell, cell_text
        from mog_drake.experiments.bench.station import bench_station

        rows = bench_station(seed)
        before = bench_cell(seed, period=0.05)  # v17 looked every 0.05 s (with a 2 m/s reach)
        cell = bench_cell(seed)
        return {what: rows, "cell": cell, "cell_before": before}, format_table(rows) + "\n" + cell_text(
            cell, before
        )
    elif what == "replanning":
        from mog_drake.experiments.bench.station import FREE_PLANNING_S, bench_replanning

        bar = Progress(2 * scenes, "replanning", enabled=progress)
        rows = bench_replanning(scenes, seed, bar, scenario, mode)
        past = f"cpu_past_{FREE_PLANNING_S:g}s"
        sums = {}
        for r in rows:
            s = sums.setdefault(r["large groups"], dict.fromkeys(("cpu_s", "first_s", past, "decisions"), 0))
            for k in s:
                s[k] += r[k]
        return {what: rows}, format_table(rows) + "\nall tables, groups of three or more with: " + "; ".join(
            f"{k} {s['cpu_s']:.1f} s of planning CPU ({s['first_s']:.1f} in first decisions, "
            f"{s[past]:.1f} past the free time), {s['decisions']} decisions"
            for k, s in sums.items()
        )
    elif what == "calibration":
        from mog_drake.experiments.bench.calibration import bench_calibration, calibration_text

        rows = bench_calibration(scenario, draws=scenes, seed=seed)
        return {what: rows}, format_table(rows) + "\n" + calibration_text(rows)
    elif what == "large":
        from mog_drake.experiments.bench.large import bench_large

        bar = Progress(5, what, enabled=progress)
        rows = bench_large(seed=seed, progress=bar)
        bar.close()
    elif what == "landing":
        from mog_drake.experiments.bench.landing import bench_landing, landing_text

        bar = Progress(30, what, enabled=progress)
        rows = bench_landing(progress=bar)
        bar.close()
        return {what: rows}, format_table(rows) + "\n" + landing_text(rows)
    elif what == "rest":
        from mog_drake.experiments.bench.station import bench_rest, rest_text

        bar = Progress(scenes, what, enabled=progress)
        doc = bench_rest(scenes, seed, progress=bar)
        bar.close()
        return doc, rest_text(doc)
    else:
        from mog_drake.errors import MogError

        raise MogError(f"unknown benchmark {what!r} (known: {', '.join(BENCHES)})")
    return {what: rows}, format_table(rows)
