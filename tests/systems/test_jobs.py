"""Jobs beside the Diagram: the CPU and wall clocks of their latency, and queueing on a thread."""

import time

import pytest

from mog_drake.config import LatencyConfig
from mog_drake.errors import MogError
from mog_drake.systems.jobs import CPU, WALL, Worker, clock_of


def _spin(seconds):
    """Busy for ``seconds`` of this thread's CPU time."""
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass
    return "spun"


def test_cpu_latency_counts_the_jobs_cpu_time_not_its_wall_time():
    """A job that sleeps 0.3 s costs no CPU time: with the ``cpu`` clock it is visible as soon
    as it is done; one that computes 0.2 s is not visible 0.1 s of simulated time after its
    request, and is 0.25 s after it (the collecting event waits for it, as in simulation)."""

    assert clock_of(LatencyConfig("cpu")) is CPU and clock_of(LatencyConfig()) is WALL
    worker = Worker("test", CPU)
    try:
        sleeper = worker.submit(time.sleep, 0.3, t_request=0.0, counter=1)
        assert sleeper.visible(0.05, None, block=True)
        assert sleeper.wall_time() >= 0.3 and sleeper.cpu_time() < 0.05
        spinner = worker.submit(_spin, 0.2, t_request=1.0, counter=2)
        assert not spinner.visible(1.1, None, block=True)
        assert spinner.visible(1.25, None, block=True)
        assert spinner.result() == "spun" and 0.2 <= spinner.cpu_time() < 0.25
    finally:
        worker.shutdown()
    wall = Worker("test", WALL)
    try:
        sleeper = wall.submit(time.sleep, 0.3, t_request=0.0, counter=1)
        assert not sleeper.visible(0.05, None, block=True)
        assert sleeper.visible(0.5, None, block=True)
    finally:
        wall.shutdown()


def _spin_then(seconds, got=None):
    """Busy for ``seconds`` of CPU, then returns ``got``."""
    _spin(seconds)
    return got


def test_a_lookahead_queued_behind_another_on_the_cpu_clock_carries_that_wait_in_its_latency():
    """On the CPU clock a job's time counts from its own start. A lookahead requested at 0.1,
    queued on its thread behind one requested at 0 that spins 0.3 s, starts where that one
    ended in simulated time, and that wait is latency: it is visible at its request plus the
    wait plus its own CPU time. On the wall clock the queueing is in its time already."""
    a = Worker("ahead", CPU)
    try:
        first = a.submit(_spin_then, 0.3, "first", t_request=0.0, counter=1)
        second = a.submit(_spin_then, 0.2, "second", t_request=0.1, counter=2)
        assert second.result() == "second"
        assert second.waited() == pytest.approx(first.cpu_time() - 0.1) and second.waited() > 0.19
        assert second.latency() == pytest.approx(second.cpu_time() + second.waited())
        end = 0.1 + second.latency()
        assert not second.visible(end - 0.05, None, block=True)
        assert second.visible(end + 1e-6, None, block=True)
    finally:
        a.shutdown()
    w = Worker("ahead", WALL)
    try:
        w.submit(_spin_then, 0.3, "first", t_request=0.0, counter=1)
        assert w.submit(_spin_then, 0.01, "second", t_request=0.1, counter=2).waited() == 0.0
    finally:
        w.shutdown()


def test_the_cpu_clock_models_a_slower_computer_by_its_reference_check(monkeypatch):
    """With ``cpu_reference_s`` three times this machine's reference check, a job that computes
    0.1 s of CPU takes 0.3 s on the job's clock: not visible 0.25 s after its request, visible
    at 0.35 s. Its CPU time stays what it was."""
    from mog_drake.sim import reference

    monkeypatch.setattr(reference, "reference_check_cpu_s", lambda: 0.2)
    slow = clock_of(LatencyConfig("cpu", cpu_reference_s=0.6))
    assert slow.name == "cpu x3.00" and not slow.from_request
    assert clock_of(LatencyConfig("fixed", cpu_reference_s=0.6)) is WALL
    worker = Worker("test", slow)
    try:
        spinner = worker.submit(_spin, 0.1, t_request=0.0, counter=1)
        assert not spinner.visible(0.25, None, block=True)
        assert spinner.visible(0.35, None, block=True)
        assert 0.1 <= spinner.cpu_time() < 0.115 and 0.3 <= spinner.clock_time() < 0.345
    finally:
        worker.shutdown()
    with pytest.raises(MogError, match="latency.cpu_reference_s"):
        LatencyConfig("cpu", cpu_reference_s=-1.0).check()
