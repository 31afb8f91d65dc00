"""Objects at rest out of reach leave the station's physics (`mog_drake.station.speed`)."""

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
    (the objects near each grasp are awake whenever it is made). Objects asleep change the
    contact problem's size, and with it its rounding: where a grasp knocks a bar over, the
    fall is chaotic and the bar lands a millimetre apart either way (table 3 did so, and its
    next grasp moved 5 mm). This table (5) tips nothing over, and takes a pair at once."""
    runs = {}
    for on in (True, False):
        sc = Scenario(scene=ClutteredScene(seed=5, n_objects=5), time_limit=60.0)
        sc.sleep = on
        sc.latency.mode = "fixed"  # the same planning latencies either way
        runs[on] = run_pick(sc)
    a, b = runs[True], runs[False]
    assert len(a.attempts) == len(b.attempts) >= 3
    for x, y in zip(a.attempts, b.attempts):
        assert x["group"] == y["group"] and x["picked"] == y["picked"]
        assert np.allclose(x["grasp"], y["grasp"], atol=1e-3)
    assert a.in_bin == b.in_bin


def test_a_station_fault_ends_the_run_with_one_line_the_record_and_the_state_saved(
    monkeypatch, tmp_path, capsys
):
    """A non-finite state ends the run (Drake's SceneGraph refuses it). Here an object is
    flung at 50 m/s a second into a run, and its velocity set to NaN a step later: the
    solver fails in the step after. The run ends with `StationFault`: one line naming the
    time, the body and how fast it moved in the last finite state, that state saved to a file
    it names, and the record of what was done; through the CLI, the record, then the line,
    exit 3."""
    import pytest

    from mog_drake.cli import main
    from mog_drake.errors import StationFault
    from mog_drake.station import speed

    update = speed.BinRetirement.update

    def fling(self, plant_context):
        update(self, plant_context)
        t = plant_context.get_time()
        if 1.0 <= t:
            v = [50.0, 0.0, 0.0] if t < 1.005 else [np.nan, 0.0, 0.0]
            self.plant.SetFreeBodySpatialVelocity(
                plant_context, self.bodies[1], SpatialVelocity(np.zeros(3), v)
            )

    monkeypatch.setattr(speed.BinRetirement, "update", fling)
    monkeypatch.chdir(tmp_path)
    sc = Scenario(scene=ClutteredScene(seed=0, n_objects=3), time_limit=20.0)
    sc.latency.mode = "fixed"
    with pytest.raises(StationFault) as fault:
        run_pick(sc)
    msg = str(fault.value)
    assert msg.startswith("the simulated station failed at t = 1.0") and "object 1 (" in msg
    assert "moved at 50 m/s" in msg and f"saved in {fault.value.path}" in msg
    saved = np.load(tmp_path / fault.value.path)
    assert (
        np.all(np.isfinite(saved["x"]))
        and 1.0 <= float(saved["t"]) < 1.01
        and "objects:" in str(saved["scene"])
    )
    assert fault.value.run.finished == "station fault" and fault.value.run.objects == 3
    (tmp_path / "sc.yaml").write_text("latency: {mode: fixed}\n")
    code = main(["pick", "--scenario", "sc.yaml", "--objects", "3", "--seed", "0", "--time-limit", "20"])
    out, err = capsys.readouterr()
    assert code == 3 and "station fault" in out
    assert (
        err.startswith("mog-drake: error: the simulated station failed at t = 1.0") and err.count("\n") == 1
    )


def test_an_object_knocked_off_the_table_spinning_lands_on_the_floor_and_sleeps():
    """The station's blow-ups (a non-finite state, an object at 1e6-1e78 m/s) were objects
    knocked off the table: with nothing under it an object fell for good, and its free-fall
    spin, which the discrete solver integrates explicitly, grew step by step until the state
    was no longer finite. Here an object leaves the table's edge turning at 200 rad/s: without
    a floor its state went non-finite 12 s later (its spin 600 rad/s by 10 s). It lands on
    the floor, comes to rest and sleeps."""
    from pydrake.math import RigidTransform, RollPitchYaw

    from mog_drake.sim.models import FLOOR_DEPTH

    sim, h, pc = still_station(Scenario(scene=ClutteredScene(seed=0, n_objects=3)))
    body = h.bodies[0]
    h.plant.SetFreeBodyPose(pc, body, RigidTransform(RollPitchYaw(0.3, 0.2, 0.1), [0.75, 0.0, 0.05]))
    h.plant.SetFreeBodySpatialVelocity(pc, body, SpatialVelocity([200.0, 140.0, 60.0], [0.5, 0.0, 0.0]))
    sleep = h.sleep(SLEEP_PERIOD)
    _advance(sim, sleep, 15.0)
    x = h.plant.GetPositionsAndVelocities(pc)
    assert np.all(np.isfinite(x))
    p = h.plant.EvalBodyPoseInWorld(pc, body).translation()
    assert abs(p[2] + FLOOR_DEPTH) < 0.05 and 0 in sleep.asleep
