"""The computer a run ran on, for its record. With ``latency.mode: cpu`` perception and
planning take their CPU time in simulated time, so a run's waits, cycle time and PPH depend
on the machine's speed as well as on the code: `compare` warns when two sweeps' runs did not
run at one speed (`speed_gap`)."""

from __future__ import annotations

import functools
import os
import platform
import time

#: Two machines whose reference checks differ by more than this factor do not pair.
SPEED_TOLERANCE = 1.25


@functools.cache
def machine() -> dict:
    """This process's machine: its CPU model, the cores it may use and ``check_cpu_s``, the
    CPU time (s) of one reference physics check (two objects in a row, closed on and lifted
    by the default check; the least of three, after one to warm up): what planning spends
    its time on. About 2 s of CPU, once per process."""
    import math

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
    return {
        "cpu": _cpu_model(),
        "cores": len(os.sched_getaffinity(0)),
        "check_cpu_s": round(min(times[1:]), 4),
    }


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def speed_gap(runs_a: list[dict], runs_b: list[dict]) -> str:
    """A line saying why runs ``runs_a`` and ``runs_b`` do not pair on timing, or "" when
    each side ran at one speed and the two agree within SPEED_TOLERANCE. A run recorded
    before machines were recorded has no ``machine``: its speed is unknown."""

    def speeds(runs):
        return [r["machine"]["check_cpu_s"] for r in runs if isinstance(r.get("machine"), dict)]

    a, b = speeds(runs_a), speeds(runs_b)
    unknown = [side for side, runs, s in (("A", runs_a, a), ("B", runs_b, b)) if len(s) < len(runs)]
    if unknown:
        return (
            f"{' and '.join(unknown)}: some runs do not record their machine; with latency.mode cpu "
            "the waits, cycle times and PPH pair only between runs on one machine"
        )
    lo, hi = min(a + b), max(a + b)
    if hi > SPEED_TOLERANCE * lo:
        return (
            f"the runs' machines differ: a reference physics check took {min(a):.2f}-{max(a):.2f} s of CPU "
            f"in A and {min(b):.2f}-{max(b):.2f} s in B; with latency.mode cpu the waits, cycle times "
            "and PPH differ by that alone"
        )
    return ""
