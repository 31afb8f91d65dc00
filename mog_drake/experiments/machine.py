"""The computer a run ran on, for its record. With ``latency.mode: cpu`` perception and
planning take their CPU time in simulated time, so a run's waits, cycle time and PPH depend
on the machine's speed as well as on the code: `compare` warns when two sweeps' runs did not
run at one speed (`speed_gap`)."""

from __future__ import annotations

import os
import platform

#: Two machines whose reference checks differ by more than this factor do not pair.
SPEED_TOLERANCE = 1.25


def machine() -> dict:
    """This process's machine: its CPU model, the cores it may use and ``check_cpu_s``, the
    CPU time of the reference physics check (`sim.reference.reference_check_cpu_s`)."""
    from mog_drake.sim.reference import reference_check_cpu_s

    return {
        "cpu": _cpu_model(),
        "cores": len(os.sched_getaffinity(0)),
        "check_cpu_s": reference_check_cpu_s(),
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
            f"{' and '.join(unknown)}: some runs do not record their machine; with measured or CPU latency "
            "the waits, cycle times and PPH pair only between runs on one machine"
        )
    lo, hi = min(a + b), max(a + b)
    if hi > SPEED_TOLERANCE * lo:
        return (
            f"the runs' machines differ: a reference physics check took {min(a):.2f}-{max(a):.2f} s of CPU "
            f"in A and {min(b):.2f}-{max(b):.2f} s in B; with measured or CPU latency the waits, cycle times "
            "and PPH differ by that alone"
        )
    return ""
