"""Planar multi-object grasp geometry: pure numpy + shapely, no Drake.

Names follow the paper "Multi-Object Grasping in the Plane": h0, h_fmin, d_fmin, S, A_i.
"""

from mog_drake.geometry.candidates import (
    candidate_grasps,
    gen_grasp_cands,
    hull_positions,
    rank_grasp_cands,
    ranked_candidates,
)
from mog_drake.geometry.conditions import (
    AREA_EPS,
    GraspEvaluation,
    PolygonSet,
    evaluate_grasps,
    grasp_failure,
    jaw_collision_free,
)
from mog_drake.geometry.gripper import GripperGeometry
from mog_drake.geometry.groups import (
    DEFAULT_GROUP_RADIUS,
    GROUPINGS,
    condition_groups,
    create_obj_groups,
    objects_at_grasp,
    objects_in_reach,
    rank_obj_groups,
    ranked_groups,
)
from mog_drake.geometry.polygon import (
    final_diameters,
    transform,
    validate_convex_polygon,
)

__all__ = [
    "AREA_EPS",
    "DEFAULT_GROUP_RADIUS",
    "GROUPINGS",
    "GraspEvaluation",
    "GripperGeometry",
    "PolygonSet",
    "candidate_grasps",
    "condition_groups",
    "create_obj_groups",
    "evaluate_grasps",
    "final_diameters",
    "gen_grasp_cands",
    "grasp_failure",
    "objects_at_grasp",
    "objects_in_reach",
    "hull_positions",
    "jaw_collision_free",
    "rank_grasp_cands",
    "ranked_candidates",
    "rank_obj_groups",
    "ranked_groups",
    "transform",
    "validate_convex_polygon",
]
