"""The clocks planning time is measured on, and the modelled one (Drake-free).

A planning job's latency is measured on its thread's clock (`mog_drake.systems.jobs`):
"wall", "cpu" (the thread's CPU time) or "modelled". Wall and CPU time depend on the machine
and on its load: CPU time excludes time the thread waited for a core, but not its slowing by
the other threads that share the caches and the memory bus (identical physics checks cost
1.32x more CPU in one 20-table run than in another, docs/experiments.md). The modelled clock
depends on neither: a thread's modelled time is what the work it has done costs under a
cost model (`WorkCost`) calibrated once on a quiet machine (``mog-drake bench checks``). The
work that counts is the physics checks and pushes, which are nearly all of a decision's CPU
(a decision that replays every verdict from memory takes about 2 ms); the physics charges
its cost (`charge`) to the thread that ran it when it ends.

So under ``latency.mode: modelled`` two runs of the same table give the same latencies, the
same board reads and so the same decisions, whatever else the machine is doing; and two
planners can be compared table by table without the noise of the machine.
"""

import contextlib
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass


@dataclass
class WorkCost:
    """Seconds of a reference core one physics simulation costs: ``check_s``, plus ``sim_s``
    and ``body_sim_s`` per object body for each simulated second. The defaults are a
    least-squares fit to the thread CPU time of the checks of Alg. 1's decisions on this
    project's 2-core machine, alone (``mog-drake bench checks`` refits it and prints its
    error; building a plant added nothing significant to the fit)."""

    check_s: float = 0.17
    sim_s: float = 0.097
    body_sim_s: float = 0.134

    def of(self, sim_time: float, bodies: int) -> float:
        """The modelled seconds of one simulation of ``sim_time`` simulated seconds with
        ``bodies`` object bodies (building its plant, if it was built, is not costed)."""
        return self.check_s + max(0.0, sim_time) * (self.sim_s + self.body_sim_s * bodies)


class Tally:
    """One thread's modelled time (s): the cost of the work it has done (``t``), plus what
    the simulation under way has cost so far, while one that may be interrupted runs
    (``under_way``: see `interruptible`)."""

    def __init__(self):
        self.t = 0.0
        self.under_way = 0.0

    def now(self) -> float:
        """The thread's modelled time (s), read from any thread: ``t`` first, so a read
        between clearing ``under_way`` and charging the whole cost is early, never late."""
        return self.t + self.under_way


_local = threading.local()


def tally() -> Tally:
    """The calling thread's tally."""
    t = getattr(_local, "tally", None)
    if t is None:
        t = _local.tally = Tally()
    return t


def charge(seconds: float) -> None:
    """Adds ``seconds`` of modelled time to the calling thread's clock."""
    tally().t += seconds


def modelled_time() -> float:
    """The calling thread's modelled time (s)."""
    return tally().now()


@contextlib.contextmanager
def interruptible(stop: Callable[[], bool] | None):
    """Within the block, a physics simulation on this thread asks ``stop()`` as it goes (every
    `INTERRUPT_PERIOD` of simulated time) and ends at once, with no verdict, once it is true:
    a plan its caller no longer needs stops mid-check instead of running the check to its end
    (the assistants: `mog_drake.planning.picking.assist`). On the modelled clock the thread's
    time moves as the simulation goes while it may be interrupted (`Tally.under_way`, set by
    the simulation before each ask), so ``stop()`` answers at the time the simulation has got
    to, and a thread that waits for this one to get past a time sees it do so mid-check.
    ``stop`` None: nothing interrupts a simulation in the block."""
    old = getattr(_local, "stop", None)
    _local.stop = stop
    try:
        yield
    finally:
        _local.stop = old


def interrupt() -> Callable[[], bool] | None:
    """The calling thread's ``stop`` (`interruptible`), or None."""
    return getattr(_local, "stop", None)


# Simulated seconds between two asks of an interruptible simulation (`interruptible`): each
# ask may read another thread's board, and on the modelled clock at most this much
# simulation, about 0.02-0.05 s of modelled time, runs past the moment its caller stopped.
INTERRUPT_PERIOD = 0.02


def caller_clock(clock: str) -> Callable[[], float]:
    """A function that reads the clock ``clock`` of whichever thread calls it: "cpu"
    (`time.thread_time`), "modelled" (`modelled_time`) or "wall"."""
    return {"cpu": time.thread_time, "modelled": modelled_time}.get(clock, time.perf_counter)


def thread_clock(clock: str | Callable[[], float]) -> Callable[[], float]:
    """The calling thread's clock ``clock`` as a function any thread can read: "wall" (the
    wall clock), "cpu" (this thread's CPU time) or "modelled" (its tally); a function is
    returned as it is (tests)."""
    if callable(clock):
        return clock
    if clock == "cpu":
        clock_id = time.pthread_getcpuclockid(threading.get_ident())
        return lambda: time.clock_gettime(clock_id)
    if clock == "modelled":
        return tally().now
    return time.perf_counter
