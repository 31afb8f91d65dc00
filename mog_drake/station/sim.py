"""The simulated station: a UR5 + gripper + table + bin + prisms + overhead RGB-D camera in one
MultibodyPlant, exporting the port contract (`mog_drake.station`). Its modelling is the grasp
verifier's too (`mog_drake.sim.models`)."""

from dataclasses import replace
from pathlib import Path

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import (
    Box,
    CollisionFilterDeclaration,
    GeometryInstance,
    MakePhongIllustrationProperties,
    MakeRenderEngineVtk,
    PerceptionProperties,
    RenderEngineVtkParams,
)
from pydrake.lcm import DrakeLcm
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlant
from pydrake.multibody.tree import PdControllerGains, SpatialInertia
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import StateInterpolatorWithDiscreteDerivative
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U, RgbdSensor
from pydrake.visualization import ApplyVisualizationConfig

from mog_drake.camera import camera_intrinsics, camera_pose
from mog_drake.errors import MogError
from mog_drake.geometry import GripperGeometry
from mog_drake.geometry.gripper import OPEN_WIDTH
from mog_drake.scenario import ClutteredScene, RowScene, Scenario, SceneFile
from mog_drake.scenes import ClutterParams, Scene, cluttered_scene, row_scene
from mog_drake.sim.models import (
    add_ballast,
    add_bin,
    add_floor,
    add_gripper_fingers,
    add_prism,
    add_table,
    contact_forces,
    drake_log_level,
    filter_gripper_self_collisions,
    pose_to_transform,
    prism_points,
)
from mog_drake.sim.realism import depth_artefacts
from mog_drake.sim.ur5 import JOINT_NAMES, URDF_PATH, base_transform, palm_in_flange

# Meshcat needs no LCM: an in-memory one keeps ApplyVisualizationConfig off the network.
_NO_LCM = DrakeLcm("memq://null")


class _DesiredState(LeafSystem):
    """Arm state [q, v] (12, the interpolated ur5.position) + gripper.position (1) -> desired
    state (8 positions, 8 velocities) of the arm's and fingers' PD actuators.

    The jaws go to a commanded opening at the gripper's speed setting (``speed``, m/s per
    jaw), as the Robotiq does: a closing command moves the fingers' setpoint at that speed,
    and the force limit stops them on contact. (A setpoint that jumped would slam the fingers
    shut at whatever speed the force limit and damping allow, several times the real one.)"""

    def __init__(self, gripper: GripperGeometry, speed: float, period: float = 0.01):
        super().__init__()
        self._t = gripper.plate_thickness
        self._max = gripper.opening - gripper.plate_thickness
        self._rate = 2.0 * speed  # opening rate (m/s), both jaws
        self._period = period
        self.DeclareVectorInputPort("arm_state", 12)
        self._cmd = self.DeclareVectorInputPort("gripper.position", 1)
        # Setpoint opening w(t) = w_k + rate_k (t - t_k) between updates: [w_k, rate_k, t_k].
        # Updated every ``period``, not every plant step: the ramp is exact in between.
        self._w = self.DeclareDiscreteState([self._max, 0.0, 0.0])  # starts open
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._advance)
        self.DeclareVectorOutputPort("desired_state", 16, self._calc)

    def _advance(self, context, discrete_state) -> None:
        t = context.get_time()
        w_k, rate, t_k = context.get_discrete_state(self._w).value()
        w = w_k + rate * (t - t_k)
        target = min(max(float(self._cmd.Eval(context)[0]), 0.0), self._max)
        rate = min(max((target - w) / self._period, -self._rate), self._rate)
        discrete_state.get_mutable_vector(self._w).SetFromVector([w, rate, t])

    def _calc(self, context, output) -> None:
        x = self.get_input_port(0).Eval(context)
        w_k, rate, t_k = context.get_discrete_state(self._w).value()
        half = (w_k + rate * (context.get_time() - t_k) + self._t) / 2
        out = np.empty(16)
        out[:6], out[6], out[7] = x[:6], -half, half
        out[8:14], out[14], out[15] = x[6:], -rate / 2, rate / 2
        output.SetFromVector(out)


class _ArmPositions(LeafSystem):
    def __init__(self, n_state_robot: int):
        super().__init__()
        self.DeclareVectorInputPort("state", n_state_robot)
        self.DeclareVectorOutputPort(
            "ur5.position_measured", 6, lambda c, o: o.SetFromVector(self.get_input_port(0).Eval(c)[:6])
        )


class _GripperState(LeafSystem):
    """Plant state -> (inner jaw opening, its rate): read from the finger joints' entries of the
    state vector (a pure function of the input)."""

    def __init__(self, plant, left, right, thickness: float):
        super().__init__()
        nq = plant.num_positions()
        self._q = (left.position_start(), right.position_start())
        self._v = (nq + left.velocity_start(), nq + right.velocity_start())
        self._t = thickness
        self.DeclareVectorInputPort("state", plant.num_multibody_states())
        self.DeclareVectorOutputPort("gripper.state_measured", 2, self._calc)

    def _calc(self, context, output) -> None:
        x = self.get_input_port(0).Eval(context)
        (ql, qr), (vl, vr) = self._q, self._v
        output.SetFromVector([x[qr] - x[ql] - self._t, x[vr] - x[vl]])


# The gripper's bodies: the palm, then the fingers.
GRIPPER_BODIES = ("palm", "left_finger", "right_finger")


class _WristForce(LeafSystem):
    """The plant's contact results -> the force the world puts on the gripper (palm and
    fingers; N, world frame): what a force sensor at the wrist reads, less the gripper's own
    weight (the UR5's getActualTCPForce, which removes the payload's)."""

    def __init__(self, plant, scene_graph, gripper_bodies):
        super().__init__()
        self._plant, self._sg = plant, scene_graph
        self._bodies = {b.index() for b in gripper_bodies}
        self.DeclareAbstractInputPort("contact_results", plant.get_contact_results_output_port().Allocate())
        self.DeclareVectorOutputPort("ur5.wrist_force", 3, self._calc)

    def _calc(self, context, output) -> None:
        mine = self._bodies
        f = np.zeros(3)
        for a, b, f_a in contact_forces(self._plant, self._sg, self.get_input_port(0).Eval(context)):
            if (a in mine) != (b in mine):
                f += f_a if a in mine else -f_a
        output.SetFromVector(f)


class _DepthArtefacts(LeafSystem):
    """(colour image, depth image) -> the depth image as a stereo depth camera delivers it:
    `realism.depth_artefacts` with the world's noise (times the D435's RMS at each pixel's
    depth), holes and flying pixels, drawn for the image's time."""

    def __init__(self, world, width: int, height: int, fx: float):
        super().__init__()
        self._world, self._fx = world, fx
        blank = AbstractValue.Make(ImageDepth32F(width, height))
        self.DeclareAbstractInputPort("rgb", AbstractValue.Make(ImageRgba8U(width, height)))
        self.DeclareAbstractInputPort("depth", blank)
        self.DeclareAbstractOutputPort("depth", lambda: blank.Clone(), self._calc)

    def _calc(self, context, output) -> None:
        w = self._world
        z = depth_artefacts(
            self.get_input_port(1).Eval(context).data[:, :, 0],
            self.get_input_port(0).Eval(context).data,
            w.depth_rng(context.get_time()),
            noise=w.depth_noise,
            holes=w.depth_holes,
            flying=w.flying_pixels,
            fx=self._fx,
        )
        output.get_mutable_value().mutable_data[:, :, 0] = z


def scene_from_spec(spec) -> Scene:
    """The objects of a scenario's ``scene``: a cluttered table, a row class, or a file."""
    if isinstance(spec, SceneFile):
        return Scene.load(spec.file)
    rng = np.random.default_rng(spec.seed)
    if isinstance(spec, RowScene):
        return row_scene(spec.row_class, rng)
    if isinstance(spec, ClutteredScene):
        return cluttered_scene(
            rng, inventory=spec.inventory, n_objects=spec.n_objects or None, params=ClutterParams()
        )
    raise MogError(f"scene must be one of !ClutteredScene, !RowScene, !SceneFile, got {spec!r}")


ARM_LEVER = 1.1  # m: the UR5's reach (0.85 m) plus the gripper's length, with room


class StationHandles:
    """What tests and the simulation driver may need beyond the ports."""

    def __init__(self, plant, scene_graph, robot, bodies, scene, camera_intrinsics, *, arm_accel, seen=None):
        self.camera_intrinsics = camera_intrinsics
        self.seen = seen or {}  # object id -> its pose error (dx, dy, dyaw) where it has one
        self.arm_accel = arm_accel  # m/s^2, bound on any point of the arm's acceleration
        self.plant = plant
        self.scene_graph = scene_graph
        self.robot = robot
        self.bodies = bodies
        self.scene = scene

    def finger_indices(self) -> set:
        """The two fingers' body indices (contact scoring: `station.scoring.finger_forces`)."""
        return {self.plant.GetBodyByName(n, self.robot).index() for n in GRIPPER_BODIES[1:]}

    def sleep(self, period: float):
        """Objects at rest out of everything's reach leave the physics (`station.speed.Sleep`),
        looked at every ``period`` s."""
        from mog_drake.station.speed import Sleep

        gripper = [self.plant.GetBodyByName(n, self.robot) for n in GRIPPER_BODIES]
        radii = {i: self.scene.shape(i).reach for i in self.bodies}
        return Sleep(
            self.plant, self.scene_graph, self.bodies, gripper, radii, period=period, accel=self.arm_accel
        )

    def seen_poses(self, period: float):
        """The objects' pose errors kept in the table's plane as they topple (`SeenPoses`),
        looked at every ``period`` s; None where no object has one."""
        if not self.seen:
            return None
        points = {i: prism_points(self.scene.shape(i)) for i in self.seen}
        from mog_drake.station.seen import SeenPoses

        return SeenPoses(self.plant, self.scene_graph, self.bodies, self.seen, period, points)


# Drake's VTK renderer draws pixel (u, v) from the ray through (u + 0.5, v + 0.5) of its
# CameraInfo model, which puts pixel centres at integer coordinates: rendered tables perceived
# with CameraInfo's own principal point came out 0.5 pixel (0.6 mm) off along both image axes
# on every table (tests/station/test_station.py measures it).
RENDERED_PIXEL_OFFSET = 0.5


def rendered_intrinsics(camera) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) of the simulated camera's images, pixel centres at integer
    coordinates (as perception and a RealSense read them)."""
    fx, fy, cx, cy = camera_intrinsics(camera)
    return fx, fy, cx - RENDERED_PIXEL_OFFSET, cy - RENDERED_PIXEL_OFFSET


def hold_still(scenario: Scenario, station, context) -> None:
    """Fixes the station's inputs: arm at its observe pose, gripper open."""
    station.GetInputPort("ur5.position").FixValue(context, np.array(scenario.robot.home))
    station.GetInputPort("gripper.position").FixValue(context, [OPEN_WIDTH])


def still_station(scenario: Scenario, scene=None):
    """(simulator, handles, plant context) of the simulated station of ``scenario`` (``scene``
    replaces its objects) with its inputs held still (`hold_still`): the objects left alone."""
    from pydrake.systems.analysis import Simulator

    station, handles = MakeSimStation(scenario, scene)
    sim = Simulator(station)
    ctx = sim.get_mutable_context()
    hold_still(scenario, station, ctx)
    return sim, handles, handles.plant.GetMyMutableContextFromRoot(ctx)


def fastest_motion(sim, plant, plant_context, bodies, until: float, step: float = 0.05) -> np.ndarray:
    """Advances ``sim`` to ``until`` in steps of ``step`` s; per body of ``bodies``, the
    fastest turn (rad/s) and the fastest speed (m/s) seen at those steps (len x 2)."""
    worst = np.zeros((len(bodies), 2))
    t0 = sim.get_context().get_time()
    for k in range(1, int(round((until - t0) / step)) + 1):
        sim.AdvanceTo(t0 + step * k)
        for i, b in enumerate(bodies):
            V = plant.EvalBodySpatialVelocityInWorld(plant_context, b)
            worst[i] = np.maximum(
                worst[i], [np.linalg.norm(V.rotational()), np.linalg.norm(V.translational())]
            )
    return worst


def render_still(scenario: Scenario, station, context=None):
    """(rgb, depth) of a simulated station at rest: arm at its observe pose, gripper open."""
    ctx = context if context is not None else station.CreateDefaultContext()
    hold_still(scenario, station, ctx)
    rgb = station.GetOutputPort("camera.rgb_image").Eval(ctx).data
    depth = station.GetOutputPort("camera.depth_image").Eval(ctx).data[:, :, 0]
    return rgb, depth


def _add_arm(plant, scenario: Scenario, world, gripper: GripperGeometry):
    """The UR5 welded at its base, the palm on its flange (at the tool centre point as built:
    ``world.tcp_offset``) and the two fingers. Returns (robot, palm, left, right), each finger
    (body, joint)."""
    contact = scenario.contact
    robot = Parser(plant).AddModels(str(URDF_PATH))[0]
    plant.WeldFrames(
        plant.world_frame(), plant.GetFrameByName("base_link", robot), base_transform(scenario.robot.base)
    )
    # (GetJointActuatorIndices(instance) is empty before Finalize: look the motors up by name.)
    for name in JOINT_NAMES:
        plant.GetJointActuatorByName(f"{name}_motor", robot).set_controller_gains(
            PdControllerGains(p=scenario.robot.kp, d=scenario.robot.kd)
        )
    # The palm hangs off the flange: palm z (up, fingers below) opposite the tool axis.
    palm = plant.AddRigidBody("palm", robot, SpatialInertia.SolidBoxWithMass(0.9, 0.09, 0.06, 0.08))
    X_FP = palm_in_flange() @ RigidTransform(world.tcp_offset)  # the tool centre point as built
    plant.WeldFrames(plant.GetFrameByName("tool0", robot), palm.body_frame(), X_FP)
    plant.RegisterVisualGeometry(
        palm, RigidTransform([0, 0, 0.045]), Box(0.09, 0.06, 0.09), "palm", np.array([0.2, 0.2, 0.2, 1.0])
    )
    finger_contact = replace(contact, mu_finger=contact.mu_finger * world.finger_friction)
    physics = replace(scenario.gripper, force_limit=scenario.gripper.force_limit * world.grip_force)
    fingers = add_gripper_fingers(plant, robot, palm, gripper, physics, finger_contact)
    return (robot, palm, *fingers)


def MakeSimStation(scenario: Scenario, scene=None, meshcat=None, board=None):
    """Builds the simulated station (see `mog_drake.station` for its ports). Returns
    (diagram, handles). ``board``: X_TB (4x4), where a printed calibration board lies on the
    table (`hardware.calibration`), seen by the camera."""
    scene = scene if scene is not None else scene_from_spec(scenario.scene)
    gripper = GripperGeometry()
    # The world's own values: the planner's model unless scenario.realism draws others.
    world = scenario.realism.draw(getattr(scenario.scene, "seed", 0), len(scene))
    contact = scenario.contact
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(contact.plant, builder)
    x0, x1, y0, y1 = scenario.table
    X_table = RigidTransform([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    table_contact = replace(contact, mu_table=contact.mu_table * world.table_friction)
    add_table(plant, table_contact, size=(x1 - x0 + 0.6, y1 - y0 + 0.4), X_WT=X_table)
    add_floor(plant, contact, X_table)
    add_bin(
        plant,
        scenario.contact,
        RigidTransform([*scenario.bin.center, 0.0]),
        inner=tuple(scenario.bin.inner),
        depth=scenario.bin.depth,
        wall=scenario.bin.wall,
    )

    robot, palm, (left, jl), (right, jr) = _add_arm(plant, scenario, world, gripper)
    plant.set_gravity_enabled(robot, False)  # a position-controlled arm tracks its command

    bodies = {
        i: add_prism(
            plant,
            scene.shape(i),
            f"object_{i}",
            contact,
            world.friction[i],
            world.mass[i],
            size=world.size_offset[i],
            seen=world.pose_offset[i],
        )
        for i in range(len(scene))
    }
    if board is not None:
        _add_board(plant, board)
    # Under the table, out of view: one loaded contact in every step (see add_ballast).
    add_ballast(plant, contact, X_table @ RigidTransform([0.0, 0.0, -0.5]))
    plant.Finalize()
    # The arm's links and gripper never collide with each other (self-collision is not
    # modelled; the motion plans keep clear), nor the base and shoulder with the table they stand on.
    arm_bodies = [plant.GetBodyByName(n, robot) for n in ["base_link"] + [f"link_{i}" for i in range(1, 7)]]
    filter_gripper_self_collisions(plant, scene_graph, arm_bodies + [palm, left, right])
    scene_graph.collision_filter_manager().Apply(
        CollisionFilterDeclaration().ExcludeBetween(
            plant.CollectRegisteredGeometries(arm_bodies[:2]),
            plant.CollectRegisteredGeometries([plant.world_body()]),
        )
    )
    for i, body in bodies.items():
        plant.SetDefaultFloatingBaseBodyPose(body, pose_to_transform(*scene.objects[i].pose))
    q_home = np.array(scenario.robot.home, dtype=float)
    for k, idx in enumerate(plant.GetJointIndices(robot)[:6]):
        plant.get_mutable_joint(idx).set_default_positions([q_home[k]])
    jl.set_default_translation(-gripper.opening / 2)
    jr.set_default_translation(gripper.opening / 2)

    # Commanded positions -> [q, v]: the velocity feed-forward a position-controlled arm has.
    interp = builder.AddSystem(StateInterpolatorWithDiscreteDerivative(6, plant.time_step(), True))
    cmd = builder.AddSystem(_DesiredState(gripper, scenario.gripper.close_speed))
    builder.Connect(interp.get_output_port(), cmd.get_input_port(0))
    builder.Connect(cmd.get_output_port(), plant.get_desired_state_input_port(robot))
    builder.ExportInput(interp.get_input_port(), "ur5.position")
    builder.ExportInput(cmd.get_input_port(1), "gripper.position")
    arm = builder.AddSystem(_ArmPositions(plant.num_multibody_states(robot)))
    builder.Connect(plant.get_state_output_port(robot), arm.get_input_port())
    builder.ExportOutput(arm.get_output_port(), "ur5.position_measured")
    gs = builder.AddSystem(_GripperState(plant, jl, jr, gripper.plate_thickness))
    builder.Connect(plant.get_state_output_port(), gs.get_input_port())
    builder.ExportOutput(gs.get_output_port(), "gripper.state_measured")
    grip = [plant.GetBodyByName(n, robot) for n in GRIPPER_BODIES]
    wrist = builder.AddSystem(_WristForce(plant, scene_graph, grip))
    builder.Connect(plant.get_contact_results_output_port(), wrist.get_input_port())
    builder.ExportOutput(wrist.get_output_port(), "ur5.wrist_force")

    _add_camera(builder, scene_graph, scenario.camera, world)
    builder.ExportOutput(plant.get_body_poses_output_port(), "sim.body_poses")
    if meshcat is not None:
        ApplyVisualizationConfig(
            scenario.visualization,
            builder,
            plant=plant,
            scene_graph=scene_graph,
            meshcat=meshcat,
            lcm=_NO_LCM,
        )
    diagram = builder.Build()
    diagram.set_name("station")
    # Any arm point's acceleration: tangential (joint acceleration) and centripetal (joint
    # speed squared) on a lever of at most ARM_LEVER, four times over for the PD's tracking.
    r = scenario.robot
    accel = 4.0 * (r.max_joint_acceleration + r.max_joint_speed**2) * ARM_LEVER
    seen = {i: world.pose_offset[i] for i in bodies if np.any(world.pose_offset[i])}
    return diagram, StationHandles(
        plant,
        scene_graph,
        robot,
        bodies,
        scene,
        rendered_intrinsics(scenario.camera),
        arm_accel=accel,
        seen=seen,
    )


def _add_board(plant, X_TB) -> None:
    """The calibration board printed on paper (`hardware.calibration.BOARD`), lying on the
    table with its frame at ``X_TB``: a textured sheet the camera renders; no collision."""
    import tempfile

    import cv2

    from mog_drake.hardware.calibration import BOARD, PAPER, board_image

    path = Path(tempfile.gettempdir()) / f"mog_drake_board_{BOARD.squares[0]}x{BOARD.squares[1]}.png"
    if not path.is_file():
        cv2.imwrite(str(path), board_image())
    w, h = BOARD.size
    X_TB = RigidTransform(np.asarray(X_TB))
    # The sheet's centre, PAPER thick, on the table; the page's frame (z up) from the board's.
    X_TP = X_TB @ RigidTransform(RotationMatrix(np.diag([1.0, -1.0, -1.0])), [w / 2, h / 2, 0.0])
    sheet = GeometryInstance(
        X_TP @ RigidTransform([0.0, 0.0, -PAPER / 2]), Box(w, h, PAPER), "calibration_board"
    )
    props = PerceptionProperties()
    props.AddProperty("phong", "diffuse_map", str(path))
    sheet.set_perception_properties(props)
    sheet.set_illustration_properties(MakePhongIllustrationProperties(np.array([0.95, 0.95, 0.95, 1.0])))
    plant.RegisterVisualGeometry(plant.world_body(), sheet)


def _add_camera(builder, scene_graph, cam, world) -> None:
    """The overhead RGB-D camera (VTK), its images exported by the port contract's names; at
    its pose as built (``world``'s calibration error) and with its depth noise."""
    scene_graph.AddRenderer(cam.renderer_name, MakeRenderEngineVtk(RenderEngineVtkParams()))
    color, depth = cam.MakeCameras()
    X_error = RigidTransform(RollPitchYaw(world.camera_tilt), [0.0, 0.0, 0.0])
    X_WC = RigidTransform(world.camera_offset) @ RigidTransform(camera_pose(cam)) @ X_error
    sensor = builder.AddSystem(RgbdSensor(scene_graph.world_frame_id(), X_WC, color, depth))
    builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
    builder.ExportOutput(sensor.color_image_output_port(), "camera.rgb_image")
    if world.depth_artefacts:
        fx = rendered_intrinsics(cam)[0]
        real = builder.AddSystem(_DepthArtefacts(world, cam.width, cam.height, fx))
        builder.Connect(sensor.color_image_output_port(), real.get_input_port(0))
        builder.Connect(sensor.depth_image_32F_output_port(), real.get_input_port(1))
        builder.ExportOutput(real.get_output_port(), "camera.depth_image")
    else:
        builder.ExportOutput(sensor.depth_image_32F_output_port(), "camera.depth_image")
    builder.ExportOutput(sensor.label_image_output_port(), "camera.label_image")


def frame_work_cell(meshcat, scenario: Scenario) -> None:
    """Points Meshcat's camera at the work cell from the front right and above: the table, the
    arm's base and the bin fill the view (the default view starts far out, where the whole cell
    is a few dozen pixels wide)."""
    x0, x1, y0, y1 = scenario.table
    bx, by, _ = scenario.robot.base
    cx, cy = scenario.bin.center
    xs, ys = [x0, x1, bx, cx], [y0, y1, by, cy]
    target = np.array([(min(xs) + max(xs)) / 2, (min(ys) + max(ys)) / 2, 0.1])
    size = max(max(xs) - min(xs), max(ys) - min(ys))
    meshcat.SetCameraPose(target + size * np.array([0.8, -0.85, 0.7]), target)
    meshcat.SetProperty("/Axes", "visible", False)


def start_meshcat(show: bool):
    """A Meshcat; with ``show`` its address on stderr, once. Drake's own INFO line about it
    is kept off stderr."""
    import logging
    import sys

    from pydrake.geometry import StartMeshcat

    with drake_log_level(logging.WARNING):
        meshcat = StartMeshcat()
    if show:
        print(f"meshcat: {meshcat.web_url()}", file=sys.stderr)
    return meshcat
