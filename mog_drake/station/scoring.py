"""Scoring from the simulated station's ground truth: what is in the bin, where the rest lies.
It stays outside the application Diagram: the application never reads ground truth."""

import numpy as np
import shapely

from mog_drake.camera import camera_sees
from mog_drake.geometry.clip import strip_extent
from mog_drake.geometry.gripper import GripperGeometry, to_grasp_frame
from mog_drake.geometry.polygon import LENGTH_TOL, convex_hull_ccw
from mog_drake.perception import within_reach
from mog_drake.scenario import Scenario
from mog_drake.sim.models import contact_forces, prism_points


def objects_in_bin(plant, plant_context, bodies, scenario: Scenario, retired=()) -> list[int]:
    """Scoring only (ground truth): objects whose centre lies inside the bin's walls, plus
    those already retired from it (see `station.speed.BinRetirement`)."""
    cx, cy = scenario.bin.center
    hx, hy = scenario.bin.inner[0] / 2, scenario.bin.inner[1] / 2
    out = []
    for i, b in bodies.items():
        if i in retired:
            out.append(i)
            continue
        p = plant.EvalBodyPoseInWorld(plant_context, b).translation()
        if abs(p[0] - cx) <= hx and abs(p[1] - cy) <= hy and p[2] < scenario.bin.depth + 0.05:
            out.append(i)
    return out


def where_left(plant, plant_context, bodies, scenario: Scenario, in_bin) -> dict:
    """Scoring only (ground truth): where each object outside the bin is."""
    x0, x1, y0, y1 = scenario.table
    reach = scenario.perception_reach()
    out = {}
    for i, b in bodies.items():
        if i in in_bin:
            continue
        p = plant.EvalBodyPoseInWorld(plant_context, b).translation()
        if p[2] < -0.02:
            where = "off the table"
        elif (
            x0 <= p[0] <= x1
            and y0 <= p[1] <= y1
            and camera_sees(scenario.camera, p)
            and within_reach(p[0], p[1], reach)
        ):
            where = "in view"
        else:
            where = "out of view"
        out[int(i)] = (where, [round(float(v), 3) for v in p])
    return out


def _on_table(plant, plant_context, body, scene, i: int):
    """Object ``i``'s true footprint (its prism at the plant's pose, upright or knocked over,
    projected on the table; convex, counter-clockwise), or None where it is not on the table:
    in the air, in the bin or on the floor."""
    X = plant.EvalBodyPoseInWorld(plant_context, body)
    if not -0.02 < X.translation()[2] < 0.08:
        return None
    return convex_hull_ccw(X.multiply(prism_points(scene.library[scene.objects[i].shape]))[:2].T)


def jaws_land_on(
    plant, plant_context, bodies, scene, grasp, *, gripper: GripperGeometry, skip=()
) -> dict[int, float]:
    """Scoring only (ground truth): the objects lying on the table where the open jaws of
    ``grasp`` come down, their true footprints (each body's prism at the plant's pose, upright
    or knocked over, projected on the table) under a jaw's plate, each with how far the plate
    lands onto it along the closing axis (m, at most the plate's thickness: the plate wholly
    on it). The planner placed the jaws clear of the objects as it perceived them; an object
    here is one a plate lands on."""
    hw, t, hy = gripper.w_g / 2, gripper.plate_thickness, gripper.plate_width / 2
    out = {}
    for i, b in bodies.items():
        if i in skip:
            continue
        footprint = _on_table(plant, plant_context, b, scene, i)
        if footprint is None:
            continue
        P = to_grasp_frame(footprint[None], np.asarray(grasp, float))
        lo, hi, has = strip_extent(P, -hy, hy)
        if not has[0]:
            continue
        depth = max(min(hi[0], -hw) - max(lo[0], -hw - t), min(hi[0], hw + t) - max(lo[0], hw))
        if depth > LENGTH_TOL:
            out[int(i)] = float(depth)
    return out


# m: a perceived object stands for a true one whose footprint's centre lies this near its own
# (the paper's cell: a 3 mm calibration shift and each object's own 3 mm error, at 3 sigma).
UNSEEN_MATCH = 0.02


def unseen(plant, plant_context, bodies, scene, perceived, scenario: Scenario, *, skip=()) -> list[int]:
    """Scoring only (ground truth): the objects lying on the table in the camera's view and
    perception's reach that the perceived scene ``perceived`` (its unrecognised blobs in its
    meta) has nothing for: no blob's outline meets the object's true footprint, and no
    perceived object is left for it within UNSEEN_MATCH of its footprint's centre (nearest
    pairs matched first, each once). The planner planned as if they were not there: perception
    missed them, or could not see them (an object lying under another counts too)."""
    reach = scenario.perception_reach()
    truth = {}
    for i, b in bodies.items():
        if i in skip:
            continue
        hull = _on_table(plant, plant_context, b, scene, i)
        if hull is None:
            continue
        footprint = shapely.Polygon(hull)
        c = footprint.centroid
        if camera_sees(scenario.camera, [c.x, c.y, 0.0]) and within_reach(c.x, c.y, reach):
            truth[int(i)] = footprint
    blobs = [shapely.Polygon(b["vertices"]) for b in perceived.meta.get("unrecognised", ())]
    truth = {i: f for i, f in truth.items() if not any(f.intersects(b) for b in blobs)}
    seen = [shapely.Polygon(perceived.polygon(k)).centroid for k in range(len(perceived))]
    pairs = sorted((f.centroid.distance(q), i, k) for i, f in truth.items() for k, q in enumerate(seen))
    matched, used = set(), set()
    for d, i, k in pairs:
        if d > UNSEEN_MATCH:
            break
        if i not in matched and k not in used:
            matched.add(i)
            used.add(k)
    return sorted(set(truth) - matched)


def finger_forces(plant, scene_graph, plant_context, fingers: set, bodies: set) -> dict:
    """Scoring only (ground truth): the magnitude of the contact force the fingers (body
    indices) put on each of ``bodies`` (body indices) touching them now, in N."""
    results = plant.get_contact_results_output_port().Eval(plant_context)
    total: dict = {}
    for a, b, f_a in contact_forces(plant, scene_graph, results):
        for body, other, f in ((a, b, f_a), (b, a, -f_a)):
            if body in bodies and other in fingers:
                total[body] = total.get(body, np.zeros(3)) + f
    return {b: float(np.linalg.norm(f)) for b, f in total.items()}
