"""Benchmarks that print tables. Speed is shown here, never asserted in tests.

`run(what, ...)` returns (doc, text) for `mog-drake bench WHAT`:

* geometry: the conditions and the candidate filter (`bench.geometry`)
* verifier, agreement, hold, bodies, table, surface, checks: the physics check
  (`bench.physics`; checks: its cost on the modelled clock against its CPU time)
* perception, station, replanning, rest: rendered tables, the station's step, replanning,
  objects at rest on the station's table (`bench.station`)
"""

from __future__ import annotations

import statistics

from mog_drake.tables import format_table

BENCHES = (
    "geometry",
    "verifier",
    "agreement",
    "perception",
    "station",
    "replanning",
    "hold",
    "bodies",
    "table",
    "surface",
    "rest",
    "checks",
)


def run(
    what: str,
    scenes: int = 20,
    seed: int = 0,
    toppled: int = 0,
    candidates: int = 60,
    window: float = 0.5,
    progress: bool = True,
    budget: float = 0.0,
) -> tuple[dict, str]:
    """Runs one benchmark; returns its document and its table as text."""
    from mog_drake.progress import Progress

    if what == "geometry":
        from mog_drake.experiments.bench.geometry import bench_geometry

        rows = bench_geometry(scenes, seed)
    elif what == "verifier":
        from mog_drake.experiments.bench.physics import bench_verifier

        rows = bench_verifier(scenes, seed)
    elif what == "perception":
        from mog_drake.experiments.bench.station import bench_perception

        rows = bench_perception(scenes, seed, toppled)
        t = [r["time_s"] for r in rows]
        text = format_table(rows) + (
            f"\nper image: median {statistics.median(t):.3f} s, worst {max(t):.3f} s; "
            f"found {sum(r['found'] for r in rows)}, missed {sum(r['missed'] for r in rows)}, "
            f"extra {sum(r['extra'] for r in rows)}; worst position {max(r['pos_max_mm'] for r in rows):.2f} mm, "
            f"worst yaw {max(r['yaw_max_deg'] for r in rows):.2f} deg"
        )
        return {what: rows}, text
    elif what == "station":
        from mog_drake.experiments.bench.station import bench_station

        rows = bench_station(seed)
    elif what == "replanning":
        from mog_drake.experiments.bench.station import bench_replanning

        rows = bench_replanning(scenes, seed, Progress(2 * scenes, "replanning", enabled=progress), budget)
    elif what == "agreement":
        from mog_drake.experiments.bench.physics import agreement_text, bench_agreement

        bar = Progress(candidates, "agreement", enabled=progress)
        doc = bench_agreement(candidates, seed, progress=bar)
        bar.close()
        return doc, agreement_text(doc)
    elif what == "hold":
        from mog_drake.experiments.bench.physics import bench_hold, hold_text

        bar = Progress(scenes, "hold", enabled=progress)
        doc = bench_hold(scenes, seed, window, progress=bar)
        bar.close()
        return doc, hold_text(doc)
    elif what == "rest":
        from mog_drake.experiments.bench.station import bench_rest, rest_text

        bar = Progress(scenes, what, enabled=progress)
        doc = bench_rest(scenes, seed, progress=bar)
        bar.close()
        return doc, rest_text(doc)
    elif what == "checks":
        from mog_drake.experiments.bench.physics import bench_checks, checks_text

        bar = Progress(scenes, what, enabled=progress)
        doc = bench_checks(scenes, seed, progress=bar)
        bar.close()
        return doc, checks_text(doc)
    elif what in ("bodies", "table", "surface"):
        from mog_drake.experiments.bench.physics import bench_pair, pair_text

        bar = Progress(scenes, what, enabled=progress)
        doc = bench_pair(what, scenes, seed, progress=bar)
        bar.close()
        return doc, pair_text(doc)
    else:
        from mog_drake.errors import MogError

        raise MogError(f"unknown benchmark {what!r} (known: {', '.join(BENCHES)})")
    return {what: rows}, format_table(rows)
