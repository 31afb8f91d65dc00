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
