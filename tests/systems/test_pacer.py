"""`WallClockPacer`: a run paced by the wall clock (hardware, ``--realtime``) never has simulated
time ahead of the wall clock, and after a slow step goes on at wall pace instead of racing to
catch up (what Drake's ``set_target_realtime_rate`` does, and what would send a real arm its
next motions in a burst)."""

import pytest

from mog_drake.systems.pacer import WallClockPacer


class Wall:
    """A wall clock and ``time.sleep`` on it: sleeping ``d`` s moves the clock ``d`` s on."""

    def __init__(self):
        self.t = 100.0

    def clock(self):
        return self.t

    def sleep(self, d):
        assert d > 0
        self.t += d


class Sim:
    """A Simulator whose ``AdvanceTo`` costs ``cost(t_next)`` s of wall time, recording the
    wall time at which each step was asked for."""

    def __init__(self, wall, cost):
        self.wall, self.cost, self.time, self.calls = wall, cost, 0.0, []

    def get_context(self):
        return self

    def get_time(self):
        return self.time

    def AdvanceTo(self, t):
        self.calls.append((self.wall.t, t))
        self.wall.t += self.cost(t)
        self.time = t


def _run(cost, t_end=0.2, step=0.01):
    wall = Wall()
    sim = Sim(wall, cost)
    WallClockPacer(sim, step=step, clock=wall.clock, sleep=wall.sleep).advance_to(t_end)
    return wall, sim


def test_simulated_time_never_ahead_of_the_wall_clock():
    wall, sim = _run(lambda t: 0.002)
    assert sim.time == pytest.approx(0.2)
    assert len(sim.calls) == 20  # one servo period a step
    start = sim.calls[0][0] - sim.calls[0][1]  # the wall clock at simulated time 0
    for at, t_next in sim.calls:
        assert at - start >= t_next - 1e-9  # each step asked for once the wall clock reached it
    assert wall.t - start == pytest.approx(0.2, abs=0.003)


def test_after_a_slow_step_no_burst():
    """A step of 0.3 s at 0.05 s: the steps after it come one servo period apart on the wall
    clock, as before it, and the run ends 0.3 s later than it would have."""
    wall, sim = _run(lambda t: 0.3 if abs(t - 0.05) < 1e-9 else 0.002)
    starts = [at for at, _ in sim.calls]
    gaps = [b - a for a, b in zip(starts, starts[1:])]
    assert max(gaps) == pytest.approx(0.31, abs=1e-6)  # the stall, then one period
    stall = next(k for k, (_, t) in enumerate(sim.calls) if abs(t - 0.05) < 1e-9)
    after = gaps[stall + 1 :]
    assert len(after) == 14 and min(after) >= 0.01 - 1e-9
    assert wall.t - (starts[0] - 0.01) == pytest.approx(0.5, abs=0.003)
