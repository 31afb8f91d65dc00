"""Objects at rest out of reach leave the station's physics (`mog_drake.station.sleep`)."""

import numpy as np
from pydrake.multibody.math import SpatialVelocity

from mog_drake.scenario import ClutteredScene, Scenario, SceneFile
from mog_drake.station import still_station
from mog_drake.systems.pick import SLEEP_PERIOD, run_pick


def _two_bars(tmp_path):
    """Two thick bars 60 mm apart on the table, far from the arm at its observe pose, and a
    cube farther off."""
    from conftest import make_scene

    path = tmp_path / "two.yaml"
    make_scene(
        [("thick_bar", 0.0, -0.2, 0.0), ("thick_bar", 0.06, -0.2, 0.0), ("small_yellow_cube", 0.2, 0.2, 0.0)]
    ).save(path)
    return Scenario(scene=SceneFile(file=str(path)))


def _advance(sim, sleep, until):
    ctx = sim.get_mutable_context()
    while ctx.get_time() < until - 1e-9:
        sim.AdvanceTo(ctx.get_time() + SLEEP_PERIOD)
        if sleep is not None:
            sleep.update(ctx)


def test_resting_objects_sleep_where_they_lay_and_a_moving_one_wakes_its_neighbour(tmp_path):
    """Both bars fall asleep and stay exactly where they lay. Then the first is sent sliding
    into the second at 0.8 m/s: the second wakes before it is touched and is pushed. Left
    asleep (no more updates), it would have been passed through and never moved: the case
    in which sleeping would change the outcome."""
    moved = {}
    for wake in (True, False):
        sim, h, pc = still_station(_two_bars(tmp_path))
        sim.Initialize()
        sleep = h.sleep(SLEEP_PERIOD)
        _advance(sim, sleep, 0.6)
        assert set(sleep.asleep) == {0, 1, 2}  # the cube too: nothing needs one awake
        rest = {i: h.plant.EvalBodyPoseInWorld(pc, b).translation().copy() for i, b in h.bodies.items()}
        _advance(sim, sleep, 1.0)
        for i in (0, 1):  # asleep: not a bit of motion
            assert np.array_equal(h.plant.EvalBodyPoseInWorld(pc, h.bodies[i]).translation(), rest[i])
        h.plant.SetFreeBodySpatialVelocity(pc, h.bodies[0], SpatialVelocity(np.zeros(3), [0.8, 0.0, 0.0]))
        if wake:
            sleep.update(sim.get_mutable_context())  # the first moves: it wakes, and its neighbour
            assert 0 not in sleep.asleep
        else:
            sleep.wake(sim.get_mutable_context(), [0])  # the first alone
        _advance(sim, sleep if wake else None, 1.5)
        moved[wake] = np.linalg.norm(h.plant.EvalBodyPoseInWorld(pc, h.bodies[1]).translation() - rest[1])
    assert moved[True] > 0.005 and moved[False] == 0.0


def test_a_table_cleared_with_resting_objects_asleep_gives_the_same_attempts():
    """A seeded 5-object table, mog: the same attempts, grasp for grasp, with sleep on and off
    (the objects near each grasp are awake whenever it is made)."""
    runs = {}
    for on in (True, False):
        sc = Scenario(scene=ClutteredScene(seed=3, n_objects=5), time_limit=60.0)
        sc.sleep = on
        sc.latency.mode = "fixed"  # the same planning latencies either way
        runs[on] = run_pick(sc)
    a, b = runs[True], runs[False]
    assert len(a.attempts) == len(b.attempts) >= 3
    for x, y in zip(a.attempts, b.attempts):
        assert x["group"] == y["group"] and x["picked"] == y["picked"]
        assert np.allclose(x["grasp"], y["grasp"], atol=1e-3)
    assert a.in_bin == b.in_bin


def test_a_station_fault_reports_its_last_finite_state(monkeypatch):
    """A non-finite state ends the run (Drake's SceneGraph refuses it); the error then says
    when, which bodies moved fastest in the last state that was still finite, and where they
    were, and what was asleep or retired. Here an object is flung at 50 m/s a second into a
    run, and its velocity set to NaN a step later: the solver fails in the step after."""
    import pytest

    from mog_drake.station import scoring
    from mog_drake.station.scoring import station_state

    sim, h, pc = still_station(Scenario(scene=ClutteredScene(seed=0, n_objects=4)))
    body = h.bodies[2]
    h.plant.SetFreeBodySpatialVelocity(pc, body, SpatialVelocity(np.zeros(3), [3.0, 0.0, 0.0]))
    x = h.plant.GetPositionsAndVelocities(pc).copy()
    line = station_state(h, x, None, [1], 12.5)
    p = h.plant.EvalBodyPoseInWorld(pc, body).translation()
    assert line.startswith("(station at t = 12.500 s") and "fastest object 2 at 3 m/s at (" in line
    assert f"({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m" in line
    assert "asleep []; retired [1])" in line

    update = scoring.BinRetirement.update

    def fling(self, plant_context):
        update(self, plant_context)
        t = plant_context.get_time()
        if 1.0 <= t:
            v = [50.0, 0.0, 0.0] if t < 1.005 else [np.nan, 0.0, 0.0]
            self.plant.SetFreeBodySpatialVelocity(
                plant_context, self.bodies[1], SpatialVelocity(np.zeros(3), v)
            )

    monkeypatch.setattr(scoring.BinRetirement, "update", fling)
    sc = Scenario(scene=ClutteredScene(seed=0, n_objects=3), time_limit=20.0)
    sc.latency.mode = "fixed"
    with pytest.raises(
        RuntimeError,
        match=r"\(station at t = 1\.0\d+ s, its last finite state \(t = 1\.0\d+ s\): fastest object 1 at 50 m/s at \(",
    ):
        run_pick(sc)
