"""Perceived poses against the truth (benchmarks and tests)."""

import math

import numpy as np

from mog_drake.perception.fitting import symmetry_order
from mog_drake.scenes import Scene

SCORING_SYMMETRY_TOL = 1e-3


def pose_errors(perceived: Scene, truth: Scene) -> list[dict]:
    """Matches each true object to the nearest unmatched perceived object of the same shape.
    Position error (m) between the polygons' centroids, yaw error modulo the shape's symmetry
    (rad): a symmetric shape turned by its symmetry is the same polygon. Symmetry is judged to
    ``SCORING_SYMMETRY_TOL`` (1 mm, the accuracy asked of perception): the library's pink
    pentagon is regular within 0.5 mm, so a fit turned by 72 deg is the same footprint, not a
    72 deg error. Unmatched: None. Also reports perceived objects matched to nothing (``extra``)."""

    def centroid(scene, k):
        return scene.polygon(k).mean(axis=0)

    used = set()
    out = []
    for i, o in enumerate(truth.objects):
        cands = [j for j, p in enumerate(perceived.objects) if p.shape == o.shape and j not in used]
        c_true = centroid(truth, i)
        if not cands:
            out.append({"object": i, "shape": o.shape, "position": None, "yaw": None})
            continue
        j = min(cands, key=lambda j: float(np.linalg.norm(centroid(perceived, j) - c_true)))
        used.add(j)
        period = 2 * math.pi / symmetry_order(truth.library[o.shape].vertices, SCORING_SYMMETRY_TOL)
        dyaw = abs(math.remainder(perceived.objects[j].theta - o.theta, period))
        out.append(
            {
                "object": i,
                "shape": o.shape,
                "position": float(np.linalg.norm(centroid(perceived, j) - c_true)),
                "offset": (centroid(perceived, j) - c_true).tolist(),  # m, x and y
                "yaw": dyaw,
            }
        )
    for j in range(len(perceived)):
        if j not in used:
            out.append(
                {
                    "object": None,
                    "shape": perceived.objects[j].shape,
                    "position": None,
                    "yaw": None,
                    "extra": True,
                }
            )
    return out
