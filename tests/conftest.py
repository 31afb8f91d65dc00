import numpy as np
import pytest

from mog_drake.scenes import Scene, SceneObject, default_library


@pytest.fixture
def lib():
    return default_library()


def make_scene(objs, group=None, **kw) -> Scene:
    """Scene from (shape, x, y, theta) tuples."""
    return Scene([SceneObject(*o) for o in objs], default_library(), group=group, **kw)


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
