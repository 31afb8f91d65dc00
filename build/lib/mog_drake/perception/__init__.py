"""Object poses from an overhead RGB-D image: what a real camera gives, never ground truth.
Pure numpy and shapely, no Drake (the Perception LeafSystem, mog_drake.systems.perception,
wraps it).

* `perceiver`: `Perceiver` and `PerceptionConfig`, the steps from images to a Scene.
* `pointcloud`: depth to points in the table frame, colour to chromaticity.
* `fitting`: clusters, seedings and the fit of library polygons to them.
* `scoring`: perceived poses against the truth.
"""

from mog_drake.perception.fitting import separate_overlaps, symmetry_order
from mog_drake.perception.perceiver import Perceiver, PerceptionConfig, within_reach
from mog_drake.perception.pointcloud import backproject, chromaticity
from mog_drake.perception.scoring import SCORING_SYMMETRY_TOL, pose_errors

__all__ = [
    "SCORING_SYMMETRY_TOL",
    "PerceptionConfig",
    "Perceiver",
    "backproject",
    "chromaticity",
    "pose_errors",
    "separate_overlaps",
    "symmetry_order",
    "within_reach",
]
