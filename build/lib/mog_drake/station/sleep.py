"""Simulation speed, not physics: objects at rest on the table, out of reach of the gripper and
of anything moving, leave the physics until something could reach them.

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
``rest_turn``, its base within ``table_height`` of the table top) for ``rest_time``, and
nothing would wake it now, with ``reach`` and ``margin`` a quarter larger. `update` runs between two
Simulator advances; the update period must not exceed ``period``.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import CollisionFilterDeclaration, GeometrySet
from pydrake.multibody.math import SpatialForce, SpatialVelocity
from pydrake.multibody.plant import ExternallyAppliedSpatialForce


class Sleep:
    def __init__(
        self,
        plant,
        scene_graph,
        bodies: dict,
        gripper_bodies: list,
        radii: dict,
        period: float = 0.01,
        accel: float = 50.0,
        finger_reach: float = 0.06,
        rest_speed: float = 0.002,
        rest_turn: float = 0.05,
        rest_time: float = 0.2,
        margin: float = 0.01,
        table_height: float = 0.005,
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
        self.asleep: dict[int, object] = {}  # object id -> its collision filter's id
        self._rest_since: dict[int, float] = {}
        self._geometry = {i: plant.CollectRegisteredGeometries([b]) for i, b in bodies.items()}

    def update(self, root_context, skip=()) -> None:
        """Wakes what could be reached before the next update, then puts to sleep what has
        rested long enough and could not be reached by then. ``skip``: ids never put to sleep
        (objects retired from the bin, parked by `BinRetirement`)."""
        plant = self.plant
        pc = plant.GetMyMutableContextFromRoot(root_context)
        sg = self.scene_graph.GetMyMutableContextFromRoot(root_context)
        t = root_context.get_time()
        ids = list(self.bodies)
        p = np.array([plant.EvalBodyPoseInWorld(pc, self.bodies[i]).translation() for i in ids])
        v = np.zeros(len(ids))
        w = np.zeros(len(ids))
        for k, i in enumerate(ids):
            V = plant.EvalBodySpatialVelocityInWorld(pc, self.bodies[i])
            v[k], w[k] = np.linalg.norm(V.translational()), np.linalg.norm(V.rotational())
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
        r = np.array([self.radii[i] for i in ids])
        moving = [k for k in range(len(ids)) if v[k] > self.rest_speed]

        def reachable(k: int, scale: float) -> bool:
            if np.min(np.linalg.norm(grip - p[k], axis=1)) < r[k] + scale * reach:
                return True
            for m in moving:
                gap = r[m] + r[k] + scale * (self.horizon * v[m] + self.margin)
                if m != k and np.linalg.norm(p[m] - p[k]) < gap:
                    return True
            return False

        mgr = self.scene_graph.collision_filter_manager(sg)
        before = set(self.asleep)
        for k, i in enumerate(ids):
            # An object asleep does not move, unless something set its state from outside.
            if i in self.asleep and (v[k] > 0 or w[k] > 0 or reachable(k, 1.0)):
                self._unfilter(mgr, i)
        everything = None
        for k, i in enumerate(ids):
            if i in self.asleep or i in skip:
                continue
            at_rest = v[k] < self.rest_speed and w[k] < self.rest_turn and abs(p[k][2]) < self.table_height
            if not at_rest:
                self._rest_since.pop(i, None)
                continue
            since = self._rest_since.setdefault(i, t)
            if t - since < self.rest_time - 1e-9 or reachable(k, 1.25):
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
