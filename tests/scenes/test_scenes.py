import math

import numpy as np
import pytest
from conftest import make_scene

from mog_drake.errors import MogError
from mog_drake.scenes import ROW_CLASSES, Scene, ShapeLibrary, cluttered_scene, row_scene


@pytest.mark.parametrize("n_class", sorted(ROW_CLASSES))
def test_row_classes_have_their_mix(n_class, lib):
    for seed in range(5):
        s = row_scene(n_class, np.random.default_rng(seed))
        assert len(s) == n_class  # the 5-object class really has 5 objects
        assert s.group == tuple(range(n_class))
        names = [o.shape for o in s.objects]
        want = ROW_CLASSES[n_class]
        assert names.count("thin_bar") == want.count("thin_bar")
        assert names.count("thick_bar") == want.count("thick_bar")
        assert sum(n in lib.irregular for n in names) == want.count("irregular")


def test_row_is_tight_and_jittered_within_bounds():
    import shapely

    for seed in range(10):
        s = row_scene(5, np.random.default_rng(seed))
        polys = s.shapely_polygons()
        xs = [o.x for o in s.objects]
        assert xs == sorted(xs)  # a row along x
        for a, b in zip(polys[:-1], polys[1:]):
            assert shapely.distance(a, b) == pytest.approx(0.001, abs=2e-5)  # 1 mm gaps
        assert all(abs(o.y) <= 0.015 for o in s.objects)


def test_generators_reproducible_by_seed():
    a = row_scene(6, np.random.default_rng(42)).to_dict()
    b = row_scene(6, np.random.default_rng(42)).to_dict()
    c = row_scene(6, np.random.default_rng(43)).to_dict()
    assert a == b and a != c
    a = cluttered_scene(np.random.default_rng(7)).to_dict()
    b = cluttered_scene(np.random.default_rng(7)).to_dict()
    assert a == b


def test_cluttered_isrr33_is_valid(lib):
    s = cluttered_scene(np.random.default_rng(0))
    assert len(s) == 33
    assert sorted(o.shape for o in s.objects) == sorted(lib.inventory("isrr33"))
    s.validate()  # no overlap, on the table


def test_yaml_roundtrip(tmp_path):
    s = row_scene(4, np.random.default_rng(1))
    s.save(tmp_path / "s.yaml")
    t = Scene.load(tmp_path / "s.yaml")
    assert t.to_dict() == s.to_dict()


def _write(tmp_path, text):
    p = tmp_path / "scene.yaml"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    "text,msg",
    [
        ("objects:\n- {shape: banana, pose: [0, 0, 0]}\n", "unknown shape 'banana'"),
        (
            "objects:\n- {shape: thin_bar, pose: [.nan, 0, 0]}\n",
            "object 0 \\(thin_bar\\): pose .* not finite",
        ),
        ("objects:\n- {shape: thin_bar, pose: [0, .inf, 0]}\n", "not finite"),
        (
            "objects:\n- {shape: thin_bar, pose: [0, 0, 0]}\n- {shape: thick_bar, pose: [0.01, 0, 0]}\n",
            "objects 0 \\(thin_bar\\) and 1 \\(thick_bar\\) overlap",
        ),
        ("objects:\n- {shape: thin_bar, pose: [0.24, 0, 0]}\n", "object 0 \\(thin_bar\\) lies off the table"),
        ("objects:\n- {shape: thin_bar, pose: [0, 0]}\n", "three numbers"),
        ("objects: [\n", "not valid YAML"),
        ("objectz: []\n", "unknown key"),
        ("objects:\n- {shape: thin_bar, pose: [0, 0, 0]}\ngroup: [3]\n", "group names object 3"),
    ],
)
def test_bad_scenes_are_refused_by_name(tmp_path, text, msg):
    with pytest.raises(MogError, match=msg):
        Scene.load(_write(tmp_path, text))


def test_small_overlap_within_tolerance_is_accepted():
    # Touching cubes sharing an edge: zero overlap area.
    make_scene([("small_yellow_cube", 0.0, 0.0, 0.0), ("small_yellow_cube", 0.025, 0.0, 0.0)]).validate()


def test_user_shapes_extend_the_library(tmp_path):
    f = tmp_path / "mine.yaml"
    f.write_text("shapes:\n  wedge:\n    vertices: [[0, 0], [0.03, 0], [0, 0.02]]\n    height: 0.02\n")
    lib = ShapeLibrary.load(f)
    assert "wedge" in lib.shapes and "thin_bar" in lib.shapes
    assert lib["wedge"].d_fmin == pytest.approx(0.03 * 0.02 / math.hypot(0.03, 0.02))


@pytest.mark.parametrize(
    "spec,msg",
    [
        ("vertices: [[0, 0], [1, 0], [1, 1], [0.9, 0.2]]\n    height: 0.02", "not a convex polygon"),
        ("vertices: [[0, 0], [0.03, 0], [0, 0.02]]\n    height: -1", "height must be a positive"),
        ("vertices: [[0, 0], [0.03, 0], [0, 0.02]]\n    height: .nan", "height must be a positive"),
        ("vertices: [[0, 0], [0.03, 0], [0, 0.02]]", "needs 'vertices' and 'height'"),
    ],
)
def test_bad_user_shapes_are_refused_by_name(tmp_path, spec, msg):
    f = tmp_path / "mine.yaml"
    f.write_text(f"shapes:\n  blob:\n    {spec}\n")
    with pytest.raises(MogError, match=msg) as e:
        ShapeLibrary.load(f)
    assert "blob" in str(e.value)


def test_overlapping_fits_are_pushed_apart():
    import shapely

    from mog_drake.perception import separate_overlaps
    from mog_drake.scenes import SceneObject, default_library

    lib = default_library()
    # A thin bar 1 mm into a thick bar lying beside it, and a far cube left alone.
    objs = [
        SceneObject("thick_bar", 0.0, 0.0, 0.0),
        SceneObject("thin_bar", 0.0, 0.0085, 0.0),
        SceneObject("small_yellow_cube", 0.1, 0.1, 0.0),
    ]
    out, moved = separate_overlaps(objs, lib)
    assert moved >= 1 and out[2] == objs[2]
    polys = [shapely.Polygon(lib[o.shape].vertices @ [[1, 0], [0, 1]] + [o.x, o.y]) for o in out]
    assert polys[0].intersection(polys[1]).area < 1e-10
    # Each moved about half the 1 mm penetration, along y only.
    assert out[0].y == pytest.approx(-0.0006, abs=2e-4) and out[1].y == pytest.approx(0.0091, abs=2e-4)
    assert out[0].x == out[1].x == 0.0
