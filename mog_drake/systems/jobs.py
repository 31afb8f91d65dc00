"""Work off the Diagram's thread, and when its result becomes visible in simulated time.

Perception and planning run as jobs on a worker thread each (`Worker`), never inside a
Diagram event: an event only starts a job or collects a finished one, so the Diagram's step
time does not depend on how long they compute, and on hardware the servo stream goes on.

Why a thread, not a process: the heavy part of planning is Drake's physics (the verifier's
``Simulator.AdvanceTo``), and pydrake releases the GIL inside it (measured: a Python thread
ticking every 1 ms kept ticking, largest gap 2 ms, through a 1.9 s ``AdvanceTo``); perception
is numpy, which releases it in its loops. A thread shares the planner, its verifier and the
scene objects without pickling them, and test fakes and patched planners work unchanged.
What is left holding the GIL (the planner's own Python) yields it every
``sys.getswitchinterval()``; `run_pick` lowers that to 1 ms while a run lasts, so the
Diagram's thread waits at most about that long for it.

Simulated time (`LatencyConfig`): a result requested at simulated time t becomes visible at
t + latency, the latency being the job's measured wall time (``measured``) or a fixed time
per stage (``fixed``), for runs comparable across machines, or the CPU time of the job's
thread (``cpu``). ``cpu`` is what the job would take on a core of its own, as on a cell where
the arm is real: in simulation, the simulator's own physics and other runs on the machine
compete with the job for cores and stretch its wall time, but not its CPU time. (Drake's
physics and numpy here are single-threaded, so the thread's CPU time is the job's.) In a simulation that runs faster
than the wall clock, a collecting event waits (on the wall clock) for a job still running
until the job has run as long as simulated time has advanced since the request: then either
the job is done, and its result is visible if its latency has passed, or it is not, and its
latency is longer than the simulated time so far. Visibility is exact to one update period whatever the simulation's speed. On hardware (``block`` False) nothing waits: a result is
visible at the first update after it is ready and its latency has passed.
"""

import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import dataclass

from mog_drake.config import LatencyConfig


class JobClock:
    """The clock a job's latency is measured on (`mog_drake.systems.jobs`): ``WALL`` (the wall
    clock; a job's time counts from its request, queueing included) or ``CPU`` (the CPU time
    of the job's own thread, from its start)."""

    def __init__(self, name: str, from_request: bool, reader: Callable[[], Callable[[], float]]):
        self.name = name
        self.from_request = from_request  # the job's time counts from its request, not its start
        self._reader = reader

    def reader(self) -> Callable[[], float]:
        """The calling thread's time on this clock, as a function any thread can read."""
        return self._reader()

    def __repr__(self) -> str:
        return f"JobClock({self.name})"


def _this_threads_cpu() -> Callable[[], float]:
    clock_id = time.pthread_getcpuclockid(threading.get_ident())
    return lambda: time.clock_gettime(clock_id)


WALL = JobClock("wall", True, lambda: time.perf_counter)
CPU = JobClock("cpu", False, _this_threads_cpu)


def clock_of(latency: LatencyConfig) -> JobClock:
    """What a measured latency is counted on: the job thread's CPU time (``cpu``; with
    ``cpu_reference_s``, scaled by it over this machine's reference check), else the wall
    clock."""
    if latency.mode != "cpu":
        return WALL
    if not latency.cpu_reference_s:
        return CPU
    from mog_drake.sim.reference import reference_check_cpu_s

    scale = latency.cpu_reference_s / reference_check_cpu_s()

    def scaled():
        read = _this_threads_cpu()
        return lambda: scale * read()

    return JobClock(f"cpu x{scale:.2f}", False, scaled)


@dataclass(frozen=True)
class JobOutcome:
    """What a finished job's future holds: its value and its times (s)."""

    value: object
    wall: float  # from the request, queueing included
    cpu: float  # the job's own thread's CPU time
    waited: float  # for the job before it, on a clock that counts from the start
    spent: float  # on the job's clock


class Job:
    """One job: its future, when it was requested (simulated time) and submitted (wall
    time). Held in abstract state, which Drake copies on every update: copies share it."""

    def __init__(
        self,
        future: Future,
        t_request: float,
        counter: int,
        t_submit: float,
        info=None,
        clock: JobClock = WALL,
        *,
        started: dict | None = None,
    ):
        self.future, self.t_request, self.counter, self.info = future, t_request, counter, info
        self.t_submit, self.clock = t_submit, clock
        self._started = started if started is not None else {}

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self

    def elapsed(self) -> float:
        """Time the job has run so far on its clock (s): wall time since it was submitted, or
        its thread's CPU time since it started, plus how late it started (`Worker.submit`)."""
        if self.clock.from_request:
            return time.perf_counter() - self.t_submit
        if "now" not in self._started:
            return 0.0
        return self._started["now"]() - self._started["t0"] + self._started["delay"]

    def t_visible(self, latency: float | None) -> float:
        """The simulated time its result became visible (it must be visible): its request plus
        its latency."""
        return self.t_request + (latency if latency is not None else self.latency())

    def visible(self, t: float, latency: float | None, block: bool) -> bool:
        """Whether the job's result is visible at simulated time ``t`` (see the module's
        docstring); ``latency`` None: its measured time on its clock. A job that raised
        re-raises here, in the Diagram's thread."""
        waited = t - self.t_request
        if latency is not None:
            if waited < latency - 1e-9:
                return False
            if not self.future.done():
                if not block:
                    return False
                self.future.result()
            return True
        while not self.future.done():
            if not block:
                return False
            ahead = waited - self.elapsed()  # simulated time past the request, beyond the job's
            if ahead <= 0:
                return False
            try:
                self.future.result(timeout=max(ahead, 1e-3))
            except FutureTimeout:
                if self.clock.from_request:
                    return False
                # CPU time runs slower than the wall clock when the job shares a core: look again.
        return self.latency() <= waited + 1e-9

    def wall_time(self) -> float:
        """The job's latency on the wall clock, request to result (s); it must be done."""
        return self.future.result().wall

    def cpu_time(self) -> float:
        """The CPU time of the job's thread while it ran (s); it must be done."""
        return self.future.result().cpu

    def clock_time(self) -> float:
        """The job's time on its clock while it ran (s; the wall time on the wall clock); it
        must be done."""
        return self.future.result().spent

    def waited(self) -> float:
        """Simulated time the job waited for its thread beyond its own clock (s; see
        `Worker.submit`); it must be done."""
        return self.future.result().waited

    def latency(self) -> float:
        """The job's measured latency on its clock, its waits included (s); it must be
        done."""
        return (self.wall_time() if self.clock.from_request else self.clock_time()) + self.waited()

    def result(self):
        return self.future.result().value


class Worker:
    """One worker thread running one system's jobs in order."""

    def __init__(self, name: str, clock: JobClock = WALL):
        self._name, self._clock = name, clock
        self._pool: ThreadPoolExecutor | None = None
        self._last: Job | None = None  # the job submitted before, which runs first

    def submit(self, fn, *args, t_request: float, counter: int, info=None) -> Job:
        """Runs ``fn(*args)`` on the worker's thread; its wall time counts from the request
        (queueing included), its CPU time from its own start. On a clock that counts from the
        start (CPU), a job requested while the one before it still ran (a lookahead sent
        while the last one, dropped, finishes) starts in simulated time where that one ended:
        that wait is part of its latency (the wall clock counts queueing already)."""
        if self._pool is None:
            self._pool = ThreadPoolExecutor(1, thread_name_prefix=self._name)
        t_submit = time.perf_counter()
        started: dict = {}
        before = self._last

        def run():
            cpu = CPU.reader()
            now = cpu if self._clock is CPU else self._clock.reader()  # one reading on CPU
            cpu0, t0 = cpu(), now()
            late = 0.0  # ``before`` is done: this thread ran it
            if before is not None and not self._clock.from_request and before.future.exception() is None:
                late = max(0.0, before.t_visible(None) - t_request)
            started.update(now=now, t0=t0, delay=late)
            out = fn(*args)
            wall, c1 = time.perf_counter() - t_submit, cpu()
            spent = c1 - cpu0 if now is cpu else now() - t0
            return JobOutcome(out, wall, c1 - cpu0, late, spent)

        self._last = Job(
            self._pool.submit(run), t_request, counter, t_submit, info, self._clock, started=started
        )
        return self._last

    def shutdown(self) -> None:
        """Lets a running job finish, then ends the thread (a job cannot be interrupted)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
