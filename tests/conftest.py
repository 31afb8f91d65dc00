import numpy as np
import pytest

from mog_drake.scenes import Scene, SceneObject, default_library


@pytest.fixture
def lib():
    return default_library()


def make_scene(objs, group=None, **kw) -> Scene:
    """Scene from (shape, x, y, theta) tuples."""
    return Scene([SceneObject(*o) for o in objs], default_library(), group=group, **kw)


@pytest.fixture(scope="session")
def replay_dir(tmp_path_factory):
    """One RGB-D frame of a 3-object table, rendered by the simulated station."""
    from mog_drake.hardware.drivers import record_frame
    from mog_drake.scenario import ClutteredScene, Scenario
    from mog_drake.station import MakeStation, rendered_intrinsics

    sc = Scenario(scene=ClutteredScene(seed=5, n_objects=3))
    d, _ = MakeStation(sc)
    ctx = d.CreateDefaultContext()
    d.GetInputPort("ur5.position").FixValue(ctx, np.array(sc.robot.home))
    d.GetInputPort("gripper.position").FixValue(ctx, [0.075])
    folder = tmp_path_factory.mktemp("frames")
    record_frame(
        folder,
        d.GetOutputPort("camera.rgb_image").Eval(ctx).data,
        d.GetOutputPort("camera.depth_image").Eval(ctx).data,
        rendered_intrinsics(sc.camera),
    )
    return folder


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def check_in_steps(cost: float, steps: int, pause: float = 0.0) -> bool:
    """A test verifier's check of ``cost`` s of modelled time, run as `DrakeVerifier` runs
    one under a caller's stop (`mog_drake.planning.clock.interruptible`): in ``steps`` equal
    steps, each after a wall-clock ``pause``; before each but the first, the thread's
    ``under_way`` is what the check has cost so far and stop() is asked. A stopped check
    charges only that much. Returns whether it was stopped (then it gives no verdict)."""
    import time

    from mog_drake.planning.clock import charge, interrupt, tally

    stop, spent = interrupt(), cost
    try:
        for k in range(steps):
            if k and stop is not None:
                tally().under_way = cost * k / steps
                if stop():
                    spent = cost * k / steps
                    return True
            time.sleep(pause)
    finally:
        tally().under_way = 0.0
        charge(spent)
    return False
