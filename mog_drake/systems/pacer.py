"""Wall-clock pacing of a simulation (hardware runs, `--realtime`)."""

import time


class WallClockPacer:
    """Advances a Simulator no faster than the wall clock, and never lets it race to catch up.

    Drake's ``set_target_realtime_rate`` runs flat out after a slow step until simulated time
    has caught up with the wall clock; on hardware that sends the next motion in a burst. Here a
    slow step's lost time is dropped instead: simulated time falls behind the wall clock for
    good, and what follows runs at wall pace. Steps are ``step`` seconds (one servo period), so
    at most one step of events follows a stall at once.
    """

    def __init__(self, simulator, step: float = 0.01, clock=time.monotonic, sleep=time.sleep):
        self.sim, self.step, self.clock, self.sleep = simulator, step, clock, sleep
        self.offset: float | None = None  # wall time minus simulated time

    def advance_to(self, t_end: float) -> None:
        ctx = self.sim.get_context()
        while ctx.get_time() < t_end - 1e-12:
            t_next = min(ctx.get_time() + self.step, t_end)
            if self.offset is None:
                self.offset = self.clock() - ctx.get_time()
            wait = self.offset + t_next - self.clock()
            if wait > 0:
                self.sleep(wait)
            self.sim.AdvanceTo(t_next)
            late = self.clock() - (self.offset + t_next)
            if late > self.step:
                self.offset += late
