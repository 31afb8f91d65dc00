import numpy as np

from mog_drake.geometry import create_obj_groups, rank_obj_groups


def test_groups_are_neighbourhoods_without_subsets():
    # 0-1-2 on a line 30 mm apart: neighbourhoods {0,1}, {0,1,2}, {1,2}; the first and last
    # are subsets of the middle one. 3 is alone.
    c = np.array([[0.0, 0.0], [0.03, 0.0], [0.06, 0.0], [0.5, 0.5]])
    groups = create_obj_groups(c, radius=0.035)
    assert groups == [(0, 1, 2), (0,), (1,), (2,), (3,)]


def test_neighbourhoods_are_not_transitive():
    # 0-1-2-3 spaced 30 mm: hoods {0,1}, {0,1,2}, {1,2,3}, {2,3}; {0,1,2} and {1,2,3} both stay.
    c = np.array([[0.0, 0.0], [0.03, 0.0], [0.06, 0.0], [0.09, 0.0]])
    groups = create_obj_groups(c, radius=0.035)
    assert (0, 1, 2) in groups and (1, 2, 3) in groups and (0, 1, 2, 3) not in groups


def test_rank_largest_first_and_skip_oversize():
    groups = [(0, 1), (0, 1, 2), (3,), (4, 5)]
    d = np.array([0.007, 0.007, 0.007, 0.03, 0.04, 0.04])
    ranked = rank_obj_groups(groups, d, w_g=0.075)
    assert ranked == [(0, 1, 2), (0, 1), (3,)]  # (4, 5) needs 80 mm > 75 mm


def _bars(xs, theta=1.5708, shape="thin_bar"):
    from conftest import make_scene

    return make_scene([(shape, x, 0.0, theta) for x in xs])


def test_condition_groups_close_on_a_row_the_radius_splits():
    from mog_drake.geometry import GripperGeometry, condition_groups

    # Four thin bars across the closing axis, 20 mm apart: 67 mm from the first's outer face
    # to the last's, inside the 75 mm stroke, so one grasp closes on all four. The radius
    # neighbourhoods stop at 35 mm: {0,1,2} and {1,2,3}. A fifth bar lies alone.
    scene = _bars([0.0, 0.02, 0.04, 0.06, 0.3])
    polys = scene.polygons()
    radius = create_obj_groups(polys.centers, radius=0.035)
    assert (0, 1, 2, 3) not in radius and (0, 1, 2) in radius
    groups = condition_groups(polys, GripperGeometry())
    assert groups == [(0, 1, 2, 3), (0,), (1,), (2,), (3,), (4,)]  # subsets out, singles last


def test_condition_groups_keep_the_diameter_condition():
    from conftest import make_scene

    from mog_drake.geometry import GripperGeometry, condition_groups

    # A thick bar (12 mm across) between two large hexagons (35 mm flat to flat), 7 mm gaps.
    # A grasp centred on the bar has material of all three in S, but their summed d_fmin
    # (about 81 mm) exceeds the 75 mm h0 it can have at most: only the two pairs are groups.
    scene = make_scene(
        [
            ("large_hexagon", 0.0, 0.0, 0.0),
            ("thick_bar", 0.0305, 0.0, 1.5708),
            ("large_hexagon", 0.061, 0.0, 0.0),
        ]
    )
    polys = scene.polygons()
    assert polys.d_fmin.sum() > 0.075
    groups = condition_groups(polys, GripperGeometry())
    assert sorted(groups[:2]) == [(0, 1), (1, 2)]
    assert groups[2:] == [(0,), (1,), (2,)]


def test_condition_groups_of_objects_no_grasp_can_join_are_singles():
    from mog_drake.geometry import GripperGeometry, condition_groups

    # 90 mm apart: no 75 mm stroke holds material of both.
    assert condition_groups(_bars([0.0, 0.09]).polygons(), GripperGeometry()) == [(0,), (1,)]
    assert condition_groups(_bars([0.0]).polygons(), GripperGeometry()) == [(0,)]


def test_ranked_groups_follow_the_grouping_asked_for():
    import pytest

    from mog_drake.errors import MogError
    from mog_drake.geometry import GripperGeometry, ranked_groups

    polys = _bars([0.0, 0.02, 0.04, 0.06, 0.3]).polygons()
    g = GripperGeometry()
    assert ranked_groups(polys, g, "radius", 0.035)[0] == (0, 1, 2)
    assert ranked_groups(polys, g, "conditions")[0] == (0, 1, 2, 3)
    # A stroke too short for three 7 mm bars: RankObjGroups drops the triples.
    assert all(len(x) < 3 for x in ranked_groups(polys, g, "radius", 0.035, w_g=0.018))
    with pytest.raises(MogError, match="grouping must be one of"):
        ranked_groups(polys, g, "nearest")
