"""Where the simulated cell's CPU goes in a pick run (`mog-drake bench station`'s second table).

A seeded isrr33 table is picked (mog) for ``sim_seconds`` of simulated time with fixed
latencies (the same decisions on any machine), stepped as `run_pick` steps it: the Diagram
advanced ``SLEEP_PERIOD`` at a time, then the bin's retirement and the sleepers' update. The
main thread's CPU (its own clock: the planning and perception jobs run on threads of their
own) is split by component and by what the arm was doing:

* each Python LeafSystem's callbacks (its updates and output calculations, timed one by one;
  a callback's time excludes other systems' callbacks it triggers), rendering included in
  perception's;
* the contact geometry (hydroelastic surfaces and point pairs), sampled: at every 5th look,
  SceneGraph's query timed once and counted for every plant step since;
* the rest of the Simulator's advance: the discrete contact solver, the multibody dynamics and
  the framework (what is left of the advance);
* sleep and retirement, between advances.
"""

from __future__ import annotations

import contextlib
import time
from collections import Counter


def bench_cell(seed: int = 0, sim_seconds: float = 40.0, period: float | None = None) -> dict:
    """The pick run's CPU per simulated second, by component and by the arm's phase;
    ``period``: the sleepers' look (default: `run_pick`'s ``SLEEP_PERIOD``)."""
    from pydrake.geometry import HydroelasticContactRepresentation
    from pydrake.systems.analysis import Simulator

    from mog_drake.config import LatencyConfig
    from mog_drake.scenario import ClutteredScene, Scenario
    from mog_drake.station.speed import BinRetirement
    from mog_drake.systems.pick import SLEEP_PERIOD, MakePickDiagram

    period = period or SLEEP_PERIOD

    sc = Scenario(scene=ClutteredScene(seed=seed), latency=LatencyConfig(mode="fixed"))
    timers = _Timers()
    with timers.installed():
        parts = MakePickDiagram(sc)
        diagram = parts.diagram
    h, controller = parts.handles, parts.controller
    plant = h.plant
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    pc = plant.GetMyContextFromRoot(ctx)
    cc = controller.GetMyContextFromRoot(ctx)
    query = h.scene_graph.get_query_output_port()
    sgc = h.scene_graph.GetMyContextFromRoot(ctx)
    rep = (
        HydroelasticContactRepresentation.kTriangle
        if sc.contact.plant.contact_surface_representation == "triangle"
        else HydroelasticContactRepresentation.kPolygon
    )
    steps = period / plant.time_step()
    retire = BinRetirement(plant, h.bodies, sc)
    sleep = h.sleep(period) if sc.sleep else None
    sim.Initialize()
    by = {k: Counter() for k in ("sim_s", "cpu_s", "awake_s", "points")}
    samples = Counter()
    advance = between = geometry = 0.0
    k = 0
    try:
        while ctx.get_time() < sim_seconds - 1e-9:
            phase = controller.state(cc).mode
            c0 = time.thread_time()
            sim.AdvanceTo(ctx.get_time() + period)
            c1 = time.thread_time()
            retire.update(pc)
            if sleep is not None:
                sleep.update(ctx, skip=retire.retired)
            c2 = time.thread_time()
            advance, between = advance + c1 - c0, between + c2 - c1
            by["sim_s"][phase] += period
            by["cpu_s"][phase] += c2 - c0
            asleep = len(sleep.asleep) if sleep is not None else 0
            by["awake_s"][phase] += (len(h.bodies) - asleep - len(retire.retired)) * period
            if k % 5 == 0:
                qo = query.Eval(sgc)
                g0 = time.thread_time()
                surfaces, pairs = qo.ComputeContactSurfacesWithFallback(rep)
                geometry += 5 * steps * (time.thread_time() - g0)
                by["points"][phase] += sum(s.num_faces() for s in surfaces) + len(pairs)
                samples[phase] += 1
            k += 1
    finally:
        parts.perception.shutdown()
        parts.planner.shutdown()
    T = ctx.get_time()
    python = timers.total
    rows = [
        {"component": f"{name} (Python)", "cpu_s_per_sim_s": cpu / T} for name, cpu in python.most_common()
    ]
    rows.append({"component": "contact geometry (sampled)", "cpu_s_per_sim_s": geometry / T})
    rest = advance - sum(python.values()) - geometry
    rows.append({"component": "contact solver, dynamics, framework (the rest)", "cpu_s_per_sim_s": rest / T})
    rows.append({"component": "sleep and bin retirement", "cpu_s_per_sim_s": between / T})
    rows.append({"component": "all (the main thread)", "cpu_s_per_sim_s": (advance + between) / T})
    phases = [
        {
            "phase": p,
            "sim_s": by["sim_s"][p],
            "cpu_s_per_sim_s": by["cpu_s"][p] / by["sim_s"][p],
            "share_pct": 100.0 * by["cpu_s"][p] / (advance + between),
            "awake": by["awake_s"][p] / by["sim_s"][p],
            "contact_points": by["points"][p] / samples[p] if samples[p] else float("nan"),
        }
        for p in by["sim_s"]
    ]
    awake = sum(by["awake_s"].values()) / T
    return {"seed": seed, "sim_s": T, "period": period, "awake": awake, "components": rows, "phases": phases}


class _Timers:
    """CPU (thread time) of the callbacks of each LeafSystem class built while `installed`:
    every callable handed to a ``Declare...`` method is wrapped. A callback's time excludes
    the callbacks it triggers (an input port evaluated through another system's output)."""

    def __init__(self):
        self.total: Counter = Counter()
        self._stack: list[list] = []  # [name, started or resumed]

    def wrap(self, name: str, fn):
        def timed(*args):
            now = time.thread_time()
            if self._stack:  # the outer callback pauses
                outer = self._stack[-1]
                self.total[outer[0]] += now - outer[1]
            self._stack.append([name, now])
            try:
                return fn(*args)
            finally:
                end = time.thread_time()
                inner = self._stack.pop()
                self.total[inner[0]] += end - inner[1]
                if self._stack:
                    self._stack[-1][1] = end

        return timed

    @contextlib.contextmanager
    def installed(self):
        from pydrake.systems.framework import LeafSystem

        saved = {m: getattr(LeafSystem, m) for m in dir(LeafSystem) if m.startswith("Declare")}
        for m, original in saved.items():

            def declare(system, *args, _original=original, **kwargs):
                name = type(system).__name__
                args = [self.wrap(name, a) if _is_callback(a) else a for a in args]
                kwargs = {k: self.wrap(name, v) if _is_callback(v) else v for k, v in kwargs.items()}
                return _original(system, *args, **kwargs)

            setattr(LeafSystem, m, declare)
        try:
            yield
        finally:
            for m, original in saved.items():
                setattr(LeafSystem, m, original)


def _is_callback(value) -> bool:
    return callable(value) and not isinstance(value, type)


def cell_text(doc: dict, before: dict | None = None) -> str:
    """The split of ``doc``; with ``before`` (the same run, sleepers looked at less often),
    both runs' totals side by side first."""
    from mog_drake.tables import format_table

    head = ""
    if before is not None:
        rows = [
            {
                "sleepers_looked_at_every_s": d["period"],
                "objects_awake": d["awake"],
                "cpu_s_per_sim_s": d["components"][-1]["cpu_s_per_sim_s"],
            }
            for d in (before, doc)
        ]
        head = (
            "\nthe same run, sleepers looked at less often (before) and as shipped\n"
            + format_table(rows)
            + "\n"
        )
    return head + (
        f"\nseed-{doc['seed']} table, mog, {doc['sim_s']:.0f} s simulated: CPU per simulated second\n"
        + format_table(doc["components"])
        + "\n\nby the arm's phase\n"
        + format_table(doc["phases"])
    )
