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


class AttemptScoring:
    """Ground truth about each attempt of a simulated pick run, read from the plant between the
    Simulator's advances (never by the application): `observe` after every advance, `score`
    once an attempt has ended and what it dropped has landed. ``gone``: the objects retired
    from the bin (`BinRetirement.retired`, kept up to date by its owner)."""

    def __init__(self, handles, scenario: Scenario, perception, root_context, gone=()):
        self.handles, self.scenario, self.gone = handles, scenario, gone
        self.perception = perception
        self.perception_context = perception.GetMyContextFromRoot(root_context)
        self.plant_context = handles.plant.GetMyContextFromRoot(root_context)
        self.fingers = handles.finger_indices()
        self.objects = {b.index() for b in handles.bodies.values()}
        # Per attempt: the objects in the air on the way to the bin; those under its open jaws
        # (`jaws_land_on`); the largest force its open fingers put on an object (N); the objects
        # in view its scene had nothing for (`unseen`).
        self.carried: dict[int, list[int]] = {}
        self.landed: dict[int, dict] = {}
        self.pressed: dict[int, float] = {}
        self.missed: dict[int, list] = {}
        self.in_bin = 0  # objects in the bin when the last attempt was scored

    def _in_bin(self) -> list[int]:
        h = self.handles
        return objects_in_bin(h.plant, self.plant_context, h.bodies, self.scenario, self.gone)

    def observe(self, state) -> None:
        """The controller's ``state`` after an advance: where the jaws of an attempt that just
        began its approach come down and what its scene missed, the force its open fingers
        put on objects on the way down, and what it lifted once it leaves for the bin."""
        if not state.attempts:
            return
        h, ctx, k = self.handles, self.plant_context, len(state.attempts) - 1
        if state.mode == "approach":
            if k not in self.landed:
                perceived = self.perception.GetOutputPort("scene").Eval(self.perception_context).scene
                if perceived is not None:
                    away = set(self.gone) | set(self._in_bin())
                    self.missed[k] = unseen(
                        h.plant, ctx, h.bodies, h.scene, perceived, self.scenario, skip=away
                    )
                grasp = state.attempts[-1]["grasp"]
                self.landed[k] = jaws_land_on(
                    h.plant, ctx, h.bodies, h.scene, grasp, gripper=GripperGeometry(), skip=self.gone
                )
            on = finger_forces(h.plant, h.scene_graph, ctx, self.fingers, self.objects)
            self.pressed[k] = max(self.pressed.get(k, 0.0), *on.values(), 0.0)
        elif state.mode == "to_bin" and k not in self.carried:
            old = set(self._in_bin())
            self.carried[k] = [
                int(i)
                for i, b in h.bodies.items()
                if i not in old and h.plant.EvalBodyPoseInWorld(ctx, b).translation()[2] > 0.08
            ]

    def score(self, k: int, attempt: dict) -> None:
        """Completes attempt ``k``'s record ``attempt`` in place: objects it put in the bin
        (``picked``) and the bin's count, what it lifted (``carried``: seen in the air as the arm
        left for the bin; those not in the bin fell on the way), where its open jaws came down
        (``jaws_on``: {object: how far a plate landed on it, mm}), the largest force its open
        fingers put on an object on the way down (``approach_force``, N, sampled at each
        advance: a real arm stops at its force limit, a UR5's 150 N), and the objects in view
        that the scene it was planned on had nothing for (``unseen``, when any)."""
        now = len(self._in_bin())
        attempt["picked"], attempt["in_bin"] = now - self.in_bin, now
        attempt["carried"] = self.carried.get(k)
        attempt["carried_shapes"] = [self.handles.scene.objects[i].shape for i in attempt["carried"] or ()]
        on = self.landed.get(k)
        attempt["jaws_on"] = None if on is None else {str(i): round(1e3 * d, 2) for i, d in on.items()}
        attempt["approach_force"] = round(self.pressed.get(k, 0.0), 1)
        if self.missed.get(k):
            attempt["unseen"] = self.missed[k]
        self.in_bin = now
