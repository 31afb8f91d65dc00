"""A reference physics check: what planning spends its CPU time on, timed on this machine.
With ``latency.mode: cpu`` a run's waits scale with the machine's speed; the reference check
names that speed (in each run's record: `mog_drake.experiments.machine`) and, with
``latency.cpu_reference_s``, models another computer (`mog_drake.systems.jobs.clock_of`)."""

from __future__ import annotations

import functools
import math
import time


@functools.cache
def reference_check_cpu_s() -> float:
    """The CPU time (s) of one physics check of the default check (a thick bar and a cube in
    a row, closed on and lifted), the least of three after one to warm up: about 0.17 s on a
    2-core AMD EPYC virtual machine. About 1.5 s of wall time, once per process."""
    from mog_drake.scenario import Scenario
    from mog_drake.scenes import Scene, SceneObject, default_library
    from mog_drake.sim.verifier import DrakeVerifier

    sc = Scenario()
    check = DrakeVerifier(sc.verifier, physics=sc.gripper)
    row = Scene(
        [
            SceneObject("thick_bar", -0.012, 0.0, math.pi / 2),
            SceneObject("small_yellow_cube", 0.010, 0.002, 0.0),
        ],
        default_library(),
    )
    times = []
    for _ in range(4):
        t = time.process_time()
        check.check(row, (0, 1), [0.0, 0.0, 0.0])
        times.append(time.process_time() - t)
    return round(min(times[1:]), 4)
