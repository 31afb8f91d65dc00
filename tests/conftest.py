import os

import numpy as np
import pytest
from hypothesis import settings

from mog_drake.scenes import Scene, SceneObject, default_library

# The gate is reproducible: property tests draw the same examples on every run. To search
# further, run them with HYPOTHESIS_PROFILE=explore (fresh random examples each time).
settings.register_profile("gate", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "gate"))


@pytest.fixture
def lib():
    return default_library()


def make_scene(objs, group=None, **kw) -> Scene:
    """Scene from (shape, x, y, theta) tuples."""
    return Scene([SceneObject(*o) for o in objs], default_library(), group=group, **kw)


@pytest.fixture(scope="session")
def replay_dir(tmp_path_factory):
    """One RGB-D frame of a 3-object table, rendered by the simulated station."""
    from mog_drake.hardware.cameras import record_frame
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


@pytest.fixture(scope="module")
def station33():
    """The station of the 33-object cluttered table of seed 11: (scenario, diagram, handles)."""
    from mog_drake.scenario import ClutteredScene, Scenario
    from mog_drake.station import MakeStation

    sc = Scenario(scene=ClutteredScene(seed=11))
    diagram, handles = MakeStation(sc)
    return sc, diagram, handles
