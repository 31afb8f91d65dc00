"""MultibodyPlant builders: table, bin, prisms and the parallel-jaw gripper, all offline.

Everything is built in code from the object library and `GripperGeometry` (the one source of
truth for the gripper's sizes), so nothing needs `package://` resolution or a network.
"""

import contextlib
import copy
import logging
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.geometry import (
    AddCompliantHydroelasticProperties,
    AddContactMaterial,
    AddRigidHydroelasticProperties,
    Box,
    CollisionFilterDeclaration,
    Convex,
    GeometryInstance,
    HalfSpace,
    MakePhongIllustrationProperties,
    PerceptionProperties,
    ProximityProperties,
    Rgba,
    Sphere,
)
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import CoulombFriction, MultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import (
    CalcSpatialInertia,
    PdControllerGains,
    PrismaticJoint,
    RevoluteJoint,
    SpatialInertia,
)

from mog_drake.config import in_range
from mog_drake.errors import MogError
from mog_drake.geometry import GripperGeometry
from mog_drake.geometry.polygon import convex_hull_ccw


class _NoDeformableHalfSpaceWarning(logging.Filter):
    """Drake warns that half-spaces take no part in deformable contact; there is none here."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "half spaces are not currently supported for deformable" not in record.getMessage()


logging.getLogger("drake").addFilter(_NoDeformableHalfSpaceWarning())


@contextlib.contextmanager
def drake_log_level(level: int):
    """Drake's log at ``level`` (a `logging` level) inside the block, as it was after it."""
    log = logging.getLogger("drake")
    before = log.level
    log.setLevel(level)
    try:
        yield
    finally:
        log.setLevel(before)


@dataclass
class ContactConfig:
    """Contact and discretisation settings.

    Hydroelastic contact with compliant prisms and rigid fingers, table and bin, and the
    `lagged` discrete approximation (point contact needs dt <= 0.5 ms for light prisms; `sap`
    diverges with Drake's default relaxation time). Time step 2 ms: on 60 random row-scene
    candidates (docs/physics.md), dt = 2, 1 and 0.5 ms gave the same verdict on
    every one, while 5 ms, though 2.4x cheaper, missed 3 of the 4 successes and invented one;
    a slower close (50 mm/s) at 5 ms still missed 3 of 4. Only 2 ms or finer tells the truth.

    Friction. Drake combines two geometries' coefficients as 2 m1 m2 / (m1 + m2). Objects and
    fingers get a realistic 0.5 (finger-object 0.5, a rubber-padded Robotiq jaw; object-object
    0.5, wood / plastic) and the table 0.3 (laminate under wood or plastic). The paper models a
    near-frictionless table (mu = 0.01 in MuJoCo) and derives its conditions for frictionless
    object-object contact; with mu = 0.01 on every pair nothing lifts, because a lift needs
    friction at the jaws: its row check (models/row_check.yaml) gives the table 0.005,
    object-table 0.0099. On that table, objects squeezed out of a grasp slide off for good.

    Contact surfaces are triangles: with polygons (one contact point per polygon) a bar lying
    on its side rested on too few points and buzzed for good at most spots of the table, and
    now and then the solver diverged (docs/physics.md, `bench rest`).
    """

    # Drake's own: time step, contact model and discrete approximation.
    plant: MultibodyPlantConfig = field(
        default_factory=lambda: MultibodyPlantConfig(
            time_step=0.002,
            discrete_contact_approximation="lagged",
            contact_model="hydroelastic_with_fallback",
            contact_surface_representation="triangle",
        )
    )
    hydroelastic_modulus: float = 5e6  # Pa, compliant prisms
    hunt_crossley_dissipation: float = 5.0  # s/m
    resolution_hint: float = 0.01  # m
    mu_object: float = 0.5
    mu_finger: float = 0.5
    mu_table: float = 0.3
    # The table's collision geometry: "box" or "halfspace". With polygon contact surfaces
    # (``plant.contact_surface_representation``) a thin bar lying on its side (a 7 mm slab)
    # rests on a handful of contact points and buzzes for good, on either table, except where
    # the box's own triangles cut its contact surface finer; with triangle surfaces it lies
    # still (docs/physics.md: `bench rest`). The pick-and-place scenario's station uses
    # triangles; the picking check a half-space (docs/physics.md compares the two tables on
    # the planner's checks). Upright objects rest either way.
    table_collision: str = "box"

    def check(self, where: str) -> None:
        # A 5 ms step already missed 3 of the 4 successes a 2 ms step saw (docs/physics.md).
        in_range(self.plant.time_step, f"{where}.plant.time_step (s)", 0, 0.01)
        in_range(self.hydroelastic_modulus, f"{where}.hydroelastic_modulus (Pa)", 0, 1e12)
        for mu in ("mu_object", "mu_finger", "mu_table"):
            in_range(getattr(self, mu), f"{where}.{mu}", 0, 10, lo_open=False)
        if self.table_collision not in ("box", "halfspace"):
            raise MogError(f"{where}.table_collision must be box or halfspace, got {self.table_collision!r}")
        if self.plant.contact_surface_representation not in ("polygon", "triangle"):
            raise MogError(
                f"{where}.plant.contact_surface_representation must be polygon or triangle, "
                f"got {self.plant.contact_surface_representation!r}"
            )


@dataclass
class GripperPhysics:
    """The gripper's dynamics: a position command with a force limit, like the Robotiq 2F-85.

    force_limit: grip force per jaw (N). The 2F-85 ranges 20-235 N; 40 N, a gentle setting,
    is the default: it holds a 7-object row of 10-30 g prisms and does not crush them.
    """

    force_limit: float = 40.0
    close_speed: float = 0.15  # m/s per jaw (the 2F-85 does 20-150 mm/s)
    finger_height: float = 0.040  # m, plate extent along z
    finger_clearance: float = 0.002  # m, gap between the plates' bottom and the table
    finger_mass: float = 0.05
    finger_kp: float = 2.0e4  # N/m: saturates at the force limit after 2 mm of error
    finger_kd: float = 60.0
    gantry_kp: float = 4.0e4
    gantry_kd: float = 800.0
    yaw_kp: float = 400.0
    yaw_kd: float = 20.0
    # The 2F-85's linkage moves both jaws together, mirror images about the palm's centre (a
    # coupler constraint, right = -left). Uncoupled, each jaw is its own force-limited motor:
    # once both push at the limit, nothing centres what they hold, and the held objects and
    # jaws slide together along the closing axis under the arm's accelerations (the station
    # dropped stacks on the way to the bin like that). The paper's row check keeps the
    # uncoupled jaws its experiments were run with (models/row_check.yaml).
    coupled: bool = True

    def check(self) -> None:
        in_range(self.force_limit, "gripper.force_limit (N)", 0, 1000)
        in_range(self.close_speed, "gripper.close_speed (m/s)", 0, 1.0)
        in_range(self.finger_height, "gripper.finger_height (m)", 0, 0.2)


def _proximity(contact: ContactConfig, mu: float, compliant: bool) -> ProximityProperties:
    props = ProximityProperties()
    AddContactMaterial(contact.hunt_crossley_dissipation, None, CoulombFriction(mu, mu), props)
    if compliant:
        AddCompliantHydroelasticProperties(contact.resolution_hint, contact.hydroelastic_modulus, props)
    else:
        AddRigidHydroelasticProperties(contact.resolution_hint, props)
    return props


def add_table(
    plant: MultibodyPlant,
    contact: ContactConfig,
    size=(1.0, 1.0),
    thickness=0.05,
    name="table",
    collision: str | None = None,
    *,
    X_WT: RigidTransform | None = None,
):
    """A rigid table whose top is the plane z = 0 of the table frame T (by default the world).

    Collision (``collision``, by default ``contact.table_collision``) is the box itself
    ("box") or a rigid half-space ("halfspace", on which a bar lying on its side never comes
    to rest: see `ContactConfig`); the visual is always the box.
    """
    collision = collision or contact.table_collision
    X_WT = X_WT or RigidTransform()
    X = X_WT @ RigidTransform([0.0, 0.0, -thickness / 2])
    box = Box(size[0], size[1], thickness)
    body = plant.world_body()
    props = _proximity(contact, contact.mu_table, False)
    if collision == "halfspace":
        plant.RegisterCollisionGeometry(body, X_WT, HalfSpace(), name, props)
    elif collision == "box":
        plant.RegisterCollisionGeometry(body, X, box, name, props)
    else:
        raise ValueError(f"table collision must be 'halfspace' or 'box', got {collision!r}")
    plant.RegisterVisualGeometry(body, X, box, name, np.array([0.72, 0.65, 0.55, 1.0]))
    return body


def add_bin(
    plant: MultibodyPlant,
    contact: ContactConfig,
    X_WB: RigidTransform,
    inner=(0.25, 0.20),
    depth=0.10,
    wall=0.01,
    *,
    name="bin",
):
    """An open-top bin welded to the world: a floor and four walls (rigid)."""
    body = plant.world_body()
    lx, ly = inner
    color = np.array([0.25, 0.30, 0.35, 1.0])
    parts = {
        "floor": (Box(lx + 2 * wall, ly + 2 * wall, wall), [0, 0, wall / 2]),
        "wall_px": (Box(wall, ly + 2 * wall, depth), [lx / 2 + wall / 2, 0, depth / 2]),
        "wall_nx": (Box(wall, ly + 2 * wall, depth), [-lx / 2 - wall / 2, 0, depth / 2]),
        "wall_py": (Box(lx, wall, depth), [0, ly / 2 + wall / 2, depth / 2]),
        "wall_ny": (Box(lx, wall, depth), [0, -ly / 2 - wall / 2, depth / 2]),
    }
    for part, (box, p) in parts.items():
        X = X_WB @ RigidTransform(p)
        plant.RegisterCollisionGeometry(body, X, box, f"{name}_{part}", _proximity(contact, 0.5, False))
        plant.RegisterVisualGeometry(body, X, box, f"{name}_{part}", color)


def contact_forces(plant, scene_graph, results) -> list[tuple]:
    """Every contact of ``results`` (the plant's ContactResults) as (body A's index, body B's
    index, the force on A, N, world frame): hydroelastic contacts' F_Ac_W is on the body of
    geometry M, a point pair's contact_force() on body B."""
    inspector = scene_graph.model_inspector()
    out = []
    for k in range(results.num_hydroelastic_contacts()):
        info = results.hydroelastic_contact_info(k)
        surface = info.contact_surface()
        a, b = (
            plant.GetBodyFromFrameId(inspector.GetFrameId(g)).index()
            for g in (surface.id_M(), surface.id_N())
        )
        out.append((a, b, info.F_Ac_W().translational()))
    for k in range(results.num_point_pair_contacts()):
        info = results.point_pair_contact_info(k)
        out.append((info.bodyA_index(), info.bodyB_index(), -info.contact_force()))
    return out


def prism_points(shape) -> np.ndarray:
    """3 x 2N corners of a library shape extruded from z = 0 to its height (body frame)."""
    v = shape.vertices
    n = len(v)
    pts = np.zeros((3, 2 * n))
    pts[:2, :n] = v.T
    pts[:2, n:] = v.T
    pts[2, n:] = shape.height
    return pts


# m: the floor under the table's top: a work cell's table stands 0.7-0.9 m tall.
FLOOR_DEPTH = 0.75


def add_floor(
    plant: MultibodyPlant, contact: ContactConfig, X_WT: RigidTransform, depth: float = FLOOR_DEPTH
):
    """The floor under the table (a rigid half-space ``depth`` below the table top, frame
    ``X_WT``; friction 0.5, no visual: the camera sees none of it past the table). An object
    knocked off the table lands on it and comes to rest, as in a real cell. (Without it, such
    an object fell for good, and its free-fall spin, integrated explicitly by the discrete
    solver, grew step by step until its state was no longer finite: docs/physics.md.)"""
    plant.RegisterCollisionGeometry(
        plant.world_body(),
        X_WT @ RigidTransform([0.0, 0.0, -depth]),
        HalfSpace(),
        "floor",
        _proximity(contact, 0.5, False),
    )


def add_ballast(plant: MultibodyPlant, contact: ContactConfig, X_WB: RigidTransform):
    """Numerics, not physics: a 100 g sphere resting on a plate of its own at ``X_WB``, with
    no visual, out of every view and reach. Drake 1.51's discrete (SAP) solver fails to
    converge on a station in which nothing is in contact while the arm settles to rest under
    its PD control: a cleared table with its objects retired, the arm still over the bin
    (`test_a_cleared_station_with_the_arm_settling_does_not_fault`). With one loaded contact
    anywhere in the plant the same steps converge; the ballast's weight on its plate is one
    in every step. A point contact (the sphere has no hydroelastic properties): the cheapest
    there is."""
    plant.RegisterCollisionGeometry(
        plant.world_body(),
        X_WB @ RigidTransform([0.0, 0.0, -0.01]),
        Box(0.1, 0.1, 0.02),
        "ballast_plate",
        _proximity(contact, 1.0, False),
    )
    instance = plant.AddModelInstance("ballast")
    body = plant.AddRigidBody("ballast", instance, SpatialInertia.SolidSphereWithMass(0.1, 0.02))
    props = ProximityProperties()
    AddContactMaterial(contact.hunt_crossley_dissipation, None, CoulombFriction(1.0, 1.0), props)
    plant.RegisterCollisionGeometry(body, RigidTransform(), Sphere(0.02), "ballast", props)
    plant.SetDefaultFloatingBaseBodyPose(body, X_WB @ RigidTransform([0.0, 0.0, 0.02]))
    return body


def add_prism(
    plant: MultibodyPlant,
    shape,
    name: str,
    contact: ContactConfig,
    friction: float = 1.0,
    mass: float = 1.0,
    *,
    size: float = 0.0,
    seen=None,
):
    """A free body for one library object: a compliant hydroelastic convex prism, mass and
    inertia from its density, its library colour. Body frame at the centre of the bottom face
    (the body-frame origin of the polygon), so a table pose (x, y, theta) is X = (x, y, 0, yaw).

    A world that is not the model (`mog_drake.sim.realism`): ``friction`` and ``mass`` scale
    its friction coefficient and density, ``size`` (m) offsets its outline (as made, not as
    drawn), and ``seen`` = (dx, dy, dyaw) in its own frame is where cameras see it: its
    perception geometry there, while its collision and illustration (Meshcat) geometry stay
    where it is."""
    import shapely

    instance = plant.AddModelInstance(name)
    vertices = shape.vertices
    if size:
        grown = shapely.Polygon(vertices).buffer(size, join_style="mitre")
        vertices = convex_hull_ccw(np.asarray(grown.exterior.coords)[:-1])
    made = replace(shape, vertices=vertices)
    convex = Convex(prism_points(made), name)
    body = plant.AddRigidBody(name, instance, CalcSpatialInertia(convex, shape.density * mass))
    mu = contact.mu_object * friction
    plant.RegisterCollisionGeometry(body, RigidTransform(), convex, name, _proximity(contact, mu, True))
    colour = np.array(shape.color)
    if seen is None or not np.any(seen):
        plant.RegisterVisualGeometry(body, RigidTransform(), convex, name, colour)
        return body
    shown = GeometryInstance(RigidTransform(), convex, name)
    shown.set_illustration_properties(MakePhongIllustrationProperties(colour))
    plant.RegisterVisualGeometry(body, shown)
    camera = GeometryInstance(
        pose_to_transform(*seen), Convex(prism_points(made), f"{name}_seen"), f"{name}_seen"
    )
    props = PerceptionProperties()
    props.AddProperty("phong", "diffuse", Rgba(*colour))
    camera.set_perception_properties(props)
    plant.RegisterVisualGeometry(body, camera)
    return body


@dataclass
class GripperHandles:
    instance: object
    palm: object
    left: object
    right: object
    joints: list  # gantry x, y, z, yaw, then left and right finger
    geometry: GripperGeometry


def add_gripper_fingers(
    plant: MultibodyPlant,
    instance,
    palm,
    gripper: GripperGeometry,
    physics: GripperPhysics,
    contact: ContactConfig,
):
    """Two finger plates on prismatic joints along the palm's x (the closing axis), each with a
    PD-controlled actuator whose effort limit is the grip force. Palm frame: origin between the
    plates at the height of their top faces, z up. Joint positions are the plates' centre x:
    left in [-opening/2, -thickness/2], right in [thickness/2, opening/2]."""
    t, w, h = gripper.plate_thickness, gripper.plate_width, physics.finger_height
    box = Box(t, w, h)
    fingers = []
    for side, sign in (("left", -1.0), ("right", 1.0)):
        body = plant.AddRigidBody(
            f"{side}_finger", instance, SpatialInertia.SolidBoxWithMass(physics.finger_mass, t, w, h)
        )
        X = RigidTransform([0.0, 0.0, -h / 2])
        plant.RegisterCollisionGeometry(
            body, X, box, f"{side}_finger", _proximity(contact, contact.mu_finger, False)
        )
        plant.RegisterVisualGeometry(body, X, box, f"{side}_finger", np.array([0.15, 0.15, 0.15, 1.0]))
        lo, hi = (-gripper.opening / 2, -t / 2) if sign < 0 else (t / 2, gripper.opening / 2)
        joint = plant.AddJoint(
            PrismaticJoint(
                f"{side}_finger_joint", palm.body_frame(), body.body_frame(), [1.0, 0.0, 0.0], lo, hi
            )
        )
        act = plant.AddJointActuator(f"{side}_finger_motor", joint, physics.force_limit)
        act.set_controller_gains(PdControllerGains(p=physics.finger_kp, d=physics.finger_kd))
        fingers.append((body, joint))
    if physics.coupled:
        # Needs a SAP-based discrete solver (sap, similar or lagged: the project's default).
        plant.AddCouplerConstraint(fingers[1][1], fingers[0][1], -1.0, 0.0)
    return fingers


def add_gantry_gripper(
    plant: MultibodyPlant, gripper: GripperGeometry, physics: GripperPhysics, contact: ContactConfig
) -> GripperHandles:
    """An arm-less verifier gripper: prismatic x, y, z and revolute yaw carriages (gravity off,
    PD-controlled), carrying the palm and the two finger plates."""
    instance = plant.AddModelInstance("gripper")
    inertia = SpatialInertia.SolidBoxWithMass(0.5, 0.05, 0.05, 0.05)
    cx = plant.AddRigidBody("carriage_x", instance, inertia)
    cy = plant.AddRigidBody("carriage_y", instance, inertia)
    cz = plant.AddRigidBody("carriage_z", instance, inertia)
    palm = plant.AddRigidBody("palm", instance, inertia)
    W = plant.world_frame()
    jx = plant.AddJoint(PrismaticJoint("gantry_x", W, cx.body_frame(), [1, 0, 0], -2.0, 2.0))
    jy = plant.AddJoint(PrismaticJoint("gantry_y", cx.body_frame(), cy.body_frame(), [0, 1, 0], -2.0, 2.0))
    jz = plant.AddJoint(PrismaticJoint("gantry_z", cy.body_frame(), cz.body_frame(), [0, 0, 1], -1.0, 2.0))
    jyaw = plant.AddJoint(RevoluteJoint("gantry_yaw", cz.body_frame(), palm.body_frame(), [0, 0, 1]))
    for j, (kp, kd) in zip(
        (jx, jy, jz, jyaw),
        [(physics.gantry_kp, physics.gantry_kd)] * 3 + [(physics.yaw_kp, physics.yaw_kd)],
    ):
        a = plant.AddJointActuator(f"{j.name()}_motor", j, 1e4)
        a.set_controller_gains(PdControllerGains(p=kp, d=kd))
    plant.RegisterVisualGeometry(
        palm,
        RigidTransform([0, 0, 0.015]),
        Box(gripper.opening + gripper.plate_thickness, gripper.plate_width * 2, 0.03),
        "palm",
        np.array([0.3, 0.3, 0.3, 0.6]),
    )
    (left, jl), (right, jr) = add_gripper_fingers(plant, instance, palm, gripper, physics, contact)
    plant.set_gravity_enabled(instance, False)
    return GripperHandles(instance, palm, left, right, [jx, jy, jz, jyaw, jl, jr], gripper)


def filter_gripper_self_collisions(plant: MultibodyPlant, scene_graph, bodies) -> None:
    """The gripper's own bodies never collide with each other."""
    ids = plant.CollectRegisteredGeometries(list(bodies))
    scene_graph.collision_filter_manager().Apply(CollisionFilterDeclaration().ExcludeWithin(ids))


def pose_to_transform(x: float, y: float, theta: float, z: float = 0.0) -> RigidTransform:
    return RigidTransform(RotationMatrix.MakeZRotation(theta), [x, y, z])


def with_time_step(contact: ContactConfig, dt: float) -> ContactConfig:
    """A copy of ``contact`` with the plant's time step set to ``dt`` (s)."""
    plant = copy.copy(contact.plant)
    plant.time_step = dt
    return replace(contact, plant=plant)
