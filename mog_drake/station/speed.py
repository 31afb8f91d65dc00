"""Simulation speed, not physics: objects at rest on the table, out of reach of the gripper and
of anything moving, leave the physics until something could reach them (`Sleep`); objects at
rest in the bin leave the scene (`BinRetirement`).

Resting prisms are nearly all of the simulated station's cost: 33 of them on the table cost
2.2 s of CPU per simulated second with the arm still, against 0.18 s with them asleep
(`mog-drake bench station`), for contact the robot never disturbs. An object asleep is taken
out of collision with everything, its velocity set to zero and its weight carried by a force
at its centre of mass (on the plant's applied-force input): with no net force and no contact
it stays exactly where it lay (to the last bit), and no contact of it is computed. It keeps
its pose, so the camera sees it, and the scoring reads it, as before. (Drake's
`RigidBody.Lock` would do the same, but with some floating bodies locked and others in
contact, Drake 1.51's discrete solver crashes.)

It wakes, before anything can touch it, when

* the gripper (palm or a finger) comes within ``reach`` of its bounding sphere: as far as the
  gripper can move in two updates at the arm's top speed, plus a finger's length;
* an awake object moving faster than ``rest_speed`` comes within its own bounding sphere, plus
  how far it moves in two updates, plus ``margin``, of the sleeper's;
* it moves itself (its state was set from outside the simulation).

An object falls asleep once it has been at rest on the table (under ``rest_speed`` and
``rest_turn``, its base within ``table_height`` of the table top), or on the floor any way up,
for ``rest_time``, and
nothing would wake it now, with ``reach`` and ``margin`` a quarter larger. `update` runs between two
Simulator advances; the update period must not exceed ``period``.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import CollisionFilterDeclaration, GeometrySet
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialForce, SpatialVelocity
from pydrake.multibody.plant import ExternallyAppliedSpatialForce

from mog_drake.scenario import Scenario
from mog_drake.sim.models import FLOOR_DEPTH
from mog_drake.station.scoring import objects_in_bin


class Sleep:
    def __init__(
        self,
        plant,
        scene_graph,
        bodies: dict,
        gripper_bodies: list,
        radii: dict,
        period: float = 0.01,
        *,
        accel: float = 50.0,
        finger_reach: float = 0.06,
        rest_speed: float = 0.002,
        rest_turn: float = 0.05,
        rest_time: float = 0.2,
        margin: float = 0.01,
        table_height: float = 0.005,
        floor: float = -FLOOR_DEPTH,
    ):
        self.plant, self.scene_graph = plant, scene_graph
        self.bodies = bodies  # object id -> body
        self.gripper_bodies = gripper_bodies
        self.radii = radii  # object id -> bounding sphere radius about its body origin (m)
        self.period = period
        self.horizon = 2 * period  # the look ahead of every reach: two updates
        self.accel = accel  # m/s^2, bound on any gripper point's acceleration
        self.finger_reach = finger_reach
        self.rest_speed, self.rest_turn, self.rest_time = rest_speed, rest_turn, rest_time
        self.margin, self.table_height = margin, table_height
        self.floor = floor  # m: the floor's height (`sim.models.add_floor`)
        self.asleep: dict[int, object] = {}  # object id -> its collision filter's id
        self._rest_since: dict[int, float] = {}
        self._geometry = {i: plant.CollectRegisteredGeometries([b]) for i, b in bodies.items()}
        self._r = np.array([radii[i] for i in bodies])
        # Where each object's origin and velocities sit in the state vector [q, v].
        nq = plant.num_positions()
        q0 = np.array([b.floating_positions_start() for b in bodies.values()])
        v0 = nq + np.array([b.floating_velocities_start_in_v() for b in bodies.values()])
        self._q_at = q0[:, None] + np.arange(4, 7)
        self._w_at, self._v_at = v0[:, None] + np.arange(0, 3), v0[:, None] + np.arange(3, 6)

    def update(self, root_context, skip=()) -> None:
        """Wakes what could be reached before the next update, then puts to sleep what has
        rested long enough and could not be reached by then. ``skip``: ids never put to sleep
        (objects retired from the bin, parked by `BinRetirement`)."""
        plant = self.plant
        pc = plant.GetMyMutableContextFromRoot(root_context)
        sg = self.scene_graph.GetMyMutableContextFromRoot(root_context)
        t = root_context.get_time()
        ids = list(self.bodies)
        # Each object's origin and speeds, read off the state vector at once (a free body's
        # position follows its quaternion; its velocity is angular, then its origin's).
        x = plant.GetPositionsAndVelocities(pc)
        p, v, w = x[self._q_at], np.linalg.norm(x[self._v_at], axis=1), np.linalg.norm(x[self._w_at], axis=1)
        grip = np.array([plant.EvalBodyPoseInWorld(pc, b).translation() for b in self.gripper_bodies])
        # How far the gripper can reach by the next look: its fastest point (a finger's length
        # from a body origin) now, and what its acceleration bound can add, plus that length.
        speed = 0.0
        for b in self.gripper_bodies:
            V = plant.EvalBodySpatialVelocityInWorld(pc, b)
            speed = max(
                speed, np.linalg.norm(V.translational()) + self.finger_reach * np.linalg.norm(V.rotational())
            )
        H = self.horizon
        reach = speed * H + 0.5 * self.accel * H * H + self.finger_reach
        r = self._r
        moving = np.flatnonzero(v > self.rest_speed)
        # Distances to the gripper's bodies and to every moving object, all at once.
        to_grip = np.sqrt(((p[:, None, :] - grip[None, :, :]) ** 2).sum(-1)).min(axis=1)
        to_moving = np.sqrt(((p[:, None, :] - p[None, moving, :]) ** 2).sum(-1))
        not_self = np.arange(len(ids))[:, None] != moving[None, :]

        def reachable_all(scale: float) -> np.ndarray:
            gap = r[:, None] + r[None, moving] + scale * (self.horizon * v[None, moving] + self.margin)
            return (to_grip < r + scale * reach) | ((to_moving < gap) & not_self).any(axis=1)

        reach_now, reach_soon = reachable_all(1.0), reachable_all(1.25)

        mgr = self.scene_graph.collision_filter_manager(sg)
        before = set(self.asleep)
        for k, i in enumerate(ids):
            # An object asleep does not move, unless something set its state from outside.
            if i in self.asleep and (v[k] > 0 or w[k] > 0 or reach_now[k]):
                self._unfilter(mgr, i)
        everything = None
        for k, i in enumerate(ids):
            if i in self.asleep or i in skip:
                continue
            # On the table, standing on its base; or lying on the floor, any way up (knocked
            # off the table: nothing will reach it there).
            supported = abs(p[k][2]) < self.table_height or p[k][2] < self.floor + self.radii[i]
            at_rest = v[k] < self.rest_speed and w[k] < self.rest_turn and supported
            if not at_rest:
                self._rest_since.pop(i, None)
                continue
            since = self._rest_since.setdefault(i, t)
            if t - since < self.rest_time - 1e-9 or reach_soon[k]:
                continue
            if everything is None:
                everything = GeometrySet(self.scene_graph.model_inspector().GetAllGeometryIds())
            self.asleep[i] = mgr.ApplyTransient(
                CollisionFilterDeclaration().ExcludeBetween(self._geometry[i], everything)
            )
            plant.SetFreeBodySpatialVelocity(pc, self.bodies[i], SpatialVelocity.Zero())
        if set(self.asleep) != before:
            self._carry(pc)

    def _carry(self, pc) -> None:
        """The weight of each object asleep, carried at its centre of mass."""
        g = self.plant.gravity_field().gravity_vector()
        forces = []
        for i in self.asleep:
            body = self.bodies[i]
            f = ExternallyAppliedSpatialForce()
            f.body_index = body.index()
            f.p_BoBq_B = body.CalcCenterOfMassInBodyFrame(pc)
            f.F_Bq_W = SpatialForce(np.zeros(3), -body.get_mass(pc) * g)
            forces.append(f)
        self.plant.get_applied_spatial_force_input_port().FixValue(pc, forces)

    def wake(self, root_context, ids=None) -> None:
        """Objects ``ids`` (None: every one) back in the physics."""
        pc = self.plant.GetMyMutableContextFromRoot(root_context)
        mgr = self.scene_graph.collision_filter_manager(
            self.scene_graph.GetMyMutableContextFromRoot(root_context)
        )
        for i in list(self.asleep) if ids is None else [i for i in ids if i in self.asleep]:
            self._unfilter(mgr, i)
        self._carry(pc)

    def _unfilter(self, mgr, i: int) -> None:
        """Object ``i`` back in collision (its weight is uncarried by the next `_carry`)."""
        mgr.RemoveDeclaration(self.asleep.pop(i))
        self._rest_since.pop(i, None)


class BinRetirement:
    """Simulation speed, not physics: an object at rest in the bin is taken out of the scene.

    A pile in the bin is the costliest contact in the station (`mog-drake bench station`: 33
    prisms piled in the bin cost over 4x the same 33 on the table, and close to 20x the
    station once the pile is retired), and
    nothing the robot does depends on it: the bin is outside the camera's view and the robot
    only drops objects into it. Retired objects are parked far above the station, each in its
    own spot, put back there with zero velocity at every check (they fall freely in between),
    and counted in the bin for good. The pile is gone, so a later drop lands on the bin floor;
    a Meshcat replay shows retired objects leave the bin."""

    PARK = np.array([20.0, 20.0, 50.0])  # m, far from everything, above the table's half-space

    def __init__(self, plant, bodies, scenario: Scenario, rest_speed: float = 0.02):
        self.plant, self.bodies, self.scenario = plant, bodies, scenario
        self.rest_speed = rest_speed
        self.retired: list[int] = []

    def update(self, plant_context) -> None:
        plant = self.plant
        for i in objects_in_bin(plant, plant_context, self.bodies, self.scenario, self.retired):
            if i in self.retired:
                continue
            v = plant.EvalBodySpatialVelocityInWorld(plant_context, self.bodies[i])
            if np.linalg.norm(v.translational()) < self.rest_speed:
                self.retired.append(i)
        for k, i in enumerate(self.retired):
            X = RigidTransform(self.PARK + [0.3 * k, 0.0, 0.0])
            plant.SetFreeBodyPose(plant_context, self.bodies[i], X)
            plant.SetFreeBodySpatialVelocity(plant_context, self.bodies[i], SpatialVelocity.Zero())
