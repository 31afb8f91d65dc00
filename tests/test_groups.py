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
