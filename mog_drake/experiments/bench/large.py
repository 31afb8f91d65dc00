"""Large tables (`mog-drake bench large`): how time and memory grow with the number of objects.

Tables of 33 to 300 isrr33 objects (the inventory repeated), each dropped uniformly over the
perceived table (0.6 x 0.8 m) clear of the bin, without overlap: more objects, denser tables. Each size runs in a
process of its own (its peak memory is its own): the station built and its first image
rendered, the station stepped SIM_S of simulated time with every object awake and the arm
still (before the sleepers take over), perception of the image, and the planner's first
decision on it (`next_pick` with the scenario's planner: its CPU time and physics checks).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

SIZES = (33, 66, 100, 200, 300)
SIM_S = 0.25  # s of simulated time the station is stepped with every object awake


def large_scene(n: int, seed: int = 0):
    """``n`` objects of the isrr33 inventory (repeated) dropped uniformly over the perceived
    table, clear of the bin, without overlap (2 mm apart at least), the largest first, seeded."""
    import numpy as np
    import shapely

    from mog_drake.errors import MogError
    from mog_drake.geometry.polygon import transform
    from mog_drake.scenario import Scenario
    from mog_drake.scenes import Scene, SceneObject, default_library

    library = default_library()
    names = [k for k, v in library.inventories["isrr33"].items() for _ in range(v * math.ceil(n / 33))]
    rng = np.random.default_rng(seed)
    names = [names[i] for i in rng.permutation(len(names))][:n]
    # The largest first: on a crowded table the small ones still fit between them.
    names.sort(key=lambda name: -library[name].area)
    sc = Scenario()
    x0, x1, y0, y1 = sc.table
    margin = 0.01
    # The table but the bin's footprint and the margin around it (as the scene generators).
    inside = shapely.box(x0 + margin, y0 + margin, x1 - margin, y1 - margin).difference(
        shapely.union_all([shapely.box(xa, ya, xb, yb) for xa, xb, ya, yb in sc.keep_out()])
    )
    tree_polys: list = []
    objects = []
    for name in names:
        shape = library[name]
        for _ in range(100_000):
            x, y = rng.uniform(x0 + margin, x1 - margin), rng.uniform(y0 + margin, y1 - margin)
            th = rng.uniform(-math.pi, math.pi)
            poly = shapely.Polygon(transform(shape.vertices, x, y, th))
            if not inside.contains(poly):
                continue
            near = (
                shapely.STRtree(tree_polys).query(poly, predicate="dwithin", distance=0.002)
                if tree_polys
                else []
            )
            if len(near) == 0:
                tree_polys.append(poly)
                objects.append(SceneObject(name, float(x), float(y), float(th)))
                break
        else:
            raise MogError(f"could not place {n} objects on the table")
    return Scene(objects, library, table=(x0, x1, y0, y1)).validate()


def measure(n: int, seed: int = 0) -> dict:
    """One table size's figures (in this process)."""
    import resource
    import time

    import numpy as np

    from mog_drake.camera import camera_pose
    from mog_drake.planning.picking import next_pick
    from mog_drake.scenario import Scenario
    from mog_drake.station import render_still, still_station
    from mog_drake.systems.pick import make_planner

    def rss_mb() -> float:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    scene = large_scene(n, seed)
    sc = Scenario()
    c = time.process_time()
    sim, h, _ = still_station(sc, scene)
    build = time.process_time() - c
    c = time.process_time()
    rgb, depth = render_still(sc, sim.get_system(), sim.get_mutable_context())
    render = time.process_time() - c
    c = time.process_time()
    sim.AdvanceTo(SIM_S)  # every object awake
    station = (time.process_time() - c) / SIM_S
    station_rss = rss_mb()
    c = time.process_time()
    seen = sc.perceiver().perceive(rgb, depth, camera_pose(sc.camera), h.camera_intrinsics)
    perception = time.process_time() - c
    planner = make_planner(sc)
    c = time.thread_time()
    decision = next_pick(seen, planner, sc.planner, np.random.default_rng(seed))
    planning = time.thread_time() - c
    return {
        "objects": n,
        "seen": len(seen),
        "build_s": build,
        "render_s": render,
        "station_cpu_per_sim_s": station,
        "perception_s": perception,
        "first_decision_cpu_s": planning,
        "physics_checks": decision.physics_checks,
        "decision": f"{decision.status} of {len(decision.group or ())}",
        "peak_rss_mb": rss_mb(),
        "station_rss_mb": station_rss,
    }


def bench_large(sizes=SIZES, seed: int = 0, progress=None) -> list[dict]:
    """`measure` for each size, each in a fresh process."""
    rows = []
    for n in sizes:
        code = f"import json; from mog_drake.experiments.bench.large import measure; print(json.dumps(measure({n}, {seed})))"
        p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=3600)
        if p.returncode != 0:
            from mog_drake.errors import MogError

            raise MogError(f"bench large: the {n}-object table failed: {p.stderr.strip().splitlines()[-1]}")
        rows.append(json.loads(p.stdout.strip().splitlines()[-1]))
        if progress is not None:
            progress.step()
    return rows
