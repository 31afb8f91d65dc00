"""The station: a simulated UR5 + gripper + table + bin + prisms + overhead RGB-D camera.

`MakeStation(scenario)` returns a Diagram whose exported ports are the contract that the
hardware station honours too, so an application diagram is wired by name only:

inputs
    ur5.position              6   commanded joint positions (rad)
    gripper.position          1   commanded inner jaw opening (m); 0 closes with the force limit
outputs
    ur5.position_measured     6   measured joint positions (rad)
    gripper.state_measured    2   inner jaw opening (m) and its rate (m/s)
    camera.rgb_image              RGBA8 image
    camera.depth_image            32F depth image (m)
simulation only (tests and scoring; the application never reads them)
    camera.label_image            per-pixel geometry label
    sim.body_poses                ground-truth body poses

World frame = table frame: origin at the centre of the table top, z up.
"""

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.yaml import yaml_load_typed
from pydrake.geometry import (
    Box,
    ClippingRange,
    CollisionFilterDeclaration,
    ColorRenderCamera,
    DepthRange,
    DepthRenderCamera,
    MakeRenderEngineVtk,
    RenderCameraCore,
    RenderEngineVtkParams,
)
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlant
from pydrake.multibody.tree import PdControllerGains, SpatialInertia
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import StateInterpolatorWithDiscreteDerivative
from pydrake.systems.sensors import CameraInfo, RgbdSensor

from mog_drake.errors import MogError
from mog_drake.geometry import GROUPINGS, GripperGeometry
from mog_drake.sim.models import (
    ContactConfig,
    GripperPhysics,
    add_bin,
    add_gripper_fingers,
    add_prism,
    add_table,
    filter_gripper_self_collisions,
    pose_to_transform,
)
from mog_drake.sim.ur5 import JOINT_NAMES, URDF_PATH

PORTS_IN = ("ur5.position", "gripper.position")
PORTS_OUT = ("ur5.position_measured", "gripper.state_measured", "camera.rgb_image", "camera.depth_image")
SIM_ONLY_PORTS = ("camera.label_image", "sim.body_poses")

#: Fingertip plane below the flange along the tool axis (m): a 2F-85 on its coupling.
FLANGE_TO_PALM = 0.110


@dataclass
class SceneSpec:
    """Where the objects come from: a scene file, or a seeded generator."""

    file: str = ""
    kind: str = "cluttered"  # cluttered | row
    seed: int = 0
    inventory: str = "isrr33"
    n_objects: int = 0  # 0: the whole inventory
    row_class: int = 3


@dataclass
class RobotSpec:
    # x, y, yaw of the UR5 base; yaw pi turns the DH zero pose (arm along -x) towards the table.
    base: list[float] = field(default_factory=lambda: [-0.50, 0.0, 3.14159265])
    # Observe pose (rad): the palm at (-0.33, 0, 0.35) m, outside the camera's view.
    home: list[float] = field(default_factory=lambda: [-0.692, -2.413, 1.965, -1.122, -1.573, -2.262])
    max_joint_speed: float = 3.14  # rad/s (the UR5 does 180 deg/s)
    max_joint_acceleration: float = 3.14  # rad/s^2
    # Horizontal distance from the base's axis within which the arm reaches a top-down grasp at
    # the table (m). IK reaches 0.86 m in every direction over the table; 2 cm are kept for a
    # grasp centred off its object. Perception reports no object whose centre lies beyond it.
    reach: float = 0.84
    kp: float = 4000.0
    kd: float = 400.0


@dataclass
class BinSpec:
    center: list[float] = field(default_factory=lambda: [-0.25, 0.38])
    inner: list[float] = field(default_factory=lambda: [0.24, 0.18])
    depth: float = 0.10
    wall: float = 0.01

    def footprint(self, margin: float = 0.0) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of the bin's outside walls, grown by ``margin``."""
        hx, hy = self.inner[0] / 2 + self.wall + margin, self.inner[1] / 2 + self.wall + margin
        cx, cy = self.center
        return (cx - hx, cx + hx, cy - hy, cy + hy)


@dataclass
class CameraSpec:
    """An overhead pinhole RGB-D camera looking straight down at the table."""

    position: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.80])
    # Rotation about the vertical (rad). At pi/2 the image's long side (640 columns) runs along
    # the table's y: objects dropped or pushed beside the bin (y ~ 0.35 m) stay in view.
    yaw: float = 1.5707963
    width: int = 640
    height: int = 480
    # 0.61 m over 480 rows, 0.82 m over 640 columns (1.3 mm per pixel): the whole perceived
    # table, so that an object pushed to its edge is still seen (at 30 deg, 0.9 mm per pixel,
    # objects pushed past |y| = 0.21 m were lost from view and left on the table).
    fov_y_deg: float = 42.0
    depth_min: float = 0.1
    depth_max: float = 2.0

    def X_WC(self) -> RigidTransform:
        """Camera pose: optical z points down at the table, x along the table's x (rotated by yaw)."""
        R = RotationMatrix.MakeZRotation(self.yaw) @ RotationMatrix(RollPitchYaw(np.pi, 0.0, 0.0))
        return RigidTransform(R, self.position)

    def info(self) -> CameraInfo:
        return CameraInfo(self.width, self.height, np.radians(self.fov_y_deg))

    def intrinsics(self) -> tuple[float, float, float, float]:
        """(fx, fy, cx, cy) in pixels."""
        k = self.info()
        return (k.focal_x(), k.focal_y(), k.center_x(), k.center_y())

    def sees(self, p_W) -> bool:
        """Whether the world point projects inside the image (in front of the camera)."""
        p_C = self.X_WC().inverse() @ np.asarray(p_W, dtype=float)
        if p_C[2] <= self.depth_min:
            return False
        fx, fy, cx, cy = self.intrinsics()
        u = fx * p_C[0] / p_C[2] + cx
        v = fy * p_C[1] / p_C[2] + cy
        return bool(0 <= u < self.width and 0 <= v < self.height)


@dataclass
class PlannerSpec:
    method: str = "gp"  # gp | rand-phys | rank-phys | rand-fil-phys
    mode: str = "mog"  # mog | sog
    n_positions: int = 70
    n_orientations: int = 7
    seed: int = 0
    # Physics checks per group before the next group is tried (0: no cap). Groups that have a
    # grasp show it early: in the planner sweep (results/planner) GP found 135 of its 136
    # grasps within 3 checks.
    max_physics_per_group: int = 4
    # mog only, an extension of Alg. 1: a candidate seen to lift part of a larger group is a
    # verified grasp of that part, taken once no larger group is left to try.
    partial_lifts: bool = True
    # Also try closing axes normal to the group's edges (first among equal-area candidates):
    # grid orientations k pi / n alone pinch a lone thin bar across its corners.
    edge_orientations: bool = True
    # A lone object is not grasped where a turn under this many degrees lets the squeeze carry
    # it on to another final diameter: a thin bar held end to end (8 deg) can be twisted out of
    # the jaws by the swing to the bin. Every other library shape has 14 deg or more.
    min_squeeze_margin_deg: float = 12.0
    # The physics check holds a lifted grasp this long before its verdict: as long as the arm
    # takes to lift it and carry it to the bin (about 2.6 s). A thin bar lying on its side,
    # held end to end by the bottom 5 mm of its end faces, lifts, creeps in the jaws and slips
    # out about 2 s later: the 0.2 s hold of the paper's experiments passes it.
    hold_s: float = 2.5
    # End that hold once every lifted object has stayed settled (under 1 mm/s) this long, 0:
    # never (an extension; see VerifierConfig.settle_window). `mog-drake bench hold` on 16
    # tables: the same verdict on all 178 checks, 33 % less time.
    settle_window_s: float = 0.5
    # After a failed physics check, try a new closing axis before other points on a failed one
    # (an extension; the paper's experiments go down the ranked list).
    vary_axis: bool = True
    # A lone object is gripped along the axis the squeeze forgives most (widest squeeze basin,
    # then total area): area alone grips a bar lying on its side end to end (an extension).
    lone_widest_basin: bool = True
    # A group found to have no grasp is not planned again while every object within its reach
    # lies where it was (an extension of Alg. 1: the same checks would give the same verdicts).
    remember_failures: bool = True
    # CreateObjGroups' radius (m): objects whose centres lie this close to one object's centre
    # form its group. The authors' robot used 35 mm, a little under half its 75 mm stroke.
    group_radius: float = 0.035
    # CreateObjGroups: "radius" (the paper's: each object's neighbours within group_radius) or
    # "conditions" (an extension: the sets of objects a grasp can close on that satisfy both
    # necessary conditions, see geometry.groups.condition_groups).
    grouping: str = "radius"
    # Before the run ends on "no grasp found", plan every group again with up to 12 more
    # physics checks each, 48 in all (an extension).
    last_resort: bool = True


@dataclass
class HardwareSpec:
    """The real robot (see the hardware runbook in the README). ``enabled`` selects it."""

    enabled: bool = False
    robot_ip: str = ""  # required: the station refuses to start without it
    gripper_port: int = 63352
    camera: str = "realsense"  # realsense | replay
    replay_dir: str = ""  # replay: folder of frame_*.npz
    replay_frame_period: float = 1e9  # s per recorded frame (default: hold the first)
    dry_run: bool = False  # log every command instead of sending it
    command_log: str = ""  # dry run: JSON-lines file (default: stderr)
    # Palm box (xmin, xmax, ymin, ymax, zmin, zmax; m, table frame); the fingertips stay inside
    # it in x and y, and above the table top.
    workspace: list[float] = field(default_factory=lambda: [-0.45, 0.45, -0.45, 0.55, 0.035, 0.65])
    max_joint_speed: float = 1.5  # rad/s in wall-clock time: a target implying more is refused
    # s of motion at max_joint_speed the stream may run ahead of the wall clock (PC jitter).
    burst_window: float = 0.03
    # m: every link frame (shoulder, elbow, wrists, flange) at least this far above the table top
    # (about a link's radius; the pick's motions keep 0.15 m or more).
    link_clearance: float = 0.05
    link_box: list[float] = field(default_factory=list)  # optional box for every link frame
    servo_period: float = 0.01  # s, servoJ streaming period (the controller's period)
    stale_after: float = 0.1  # s without a new RTDE timestamp before the robot state is stale
    gripper_timeout: float = 1.0  # s, hard deadline of one gripper request
    gripper_activation_timeout: float = 5.0  # s for the gripper's activation (STA 3)
    gripper_move_timeout: float = 5.0  # s for a gripper move to end (OBJ non-zero)


@dataclass
class Scenario:
    """Everything a pick-and-place run depends on. Defaults run with no file at all."""

    scene: SceneSpec = field(default_factory=SceneSpec)
    robot: RobotSpec = field(default_factory=RobotSpec)
    bin: BinSpec = field(default_factory=BinSpec)
    camera: CameraSpec = field(default_factory=CameraSpec)
    # The world's contact: a real table has friction (0.3 here: laminate under wood or plastic).
    # On the paper's near-frictionless table, objects squeezed out of a grasp slide off the
    # table for good.
    contact: ContactConfig = field(default_factory=lambda: ContactConfig(mu_table=0.3))
    # The grasp verifier's model. By default the world's own: table friction changes how
    # pushed objects turn and slide, and with the paper's near-frictionless table (mu_table
    # 0.005, the row experiments' model) the verifier promised groups the world did not lift.
    planner_contact: ContactConfig = field(default_factory=lambda: ContactConfig(mu_table=0.3))
    # Coupled jaws, as on the 2F-85 (see GripperPhysics.coupled), in the station and in the
    # planner's physics check alike.
    gripper: GripperPhysics = field(default_factory=lambda: GripperPhysics(coupled=True))
    planner: PlannerSpec = field(default_factory=PlannerSpec)
    # The perceived table (xmin, xmax, ymin, ymax): where perception looks for objects (within
    # the arm's reach, robot.reach). The camera sees all of it; the table under it is larger.
    table: list[float] = field(default_factory=lambda: [-0.30, 0.30, -0.40, 0.40])
    time_limit: float = 600.0  # s of simulated robot time
    hardware: HardwareSpec = field(default_factory=HardwareSpec)

    def perception_ignore(self) -> list[tuple[float, float, float, float]]:
        """Regions where perception looks for no object: the bin and 5 mm around it (the
        camera sees the outside of its walls)."""
        return [self.bin.footprint(0.005)]

    def perception_reach(self) -> tuple[float, float, float]:
        """(x, y, radius): the disc about the robot's base within which the arm reaches."""
        bx, by, _ = self.robot.base
        return (float(bx), float(by), float(self.robot.reach))

    def perceiver(self, library=None):
        """A Perceiver of this scenario's perceived table: its ignored regions and the arm's
        reach (what the Perception system uses)."""
        from mog_drake.perception import Perceiver

        return Perceiver(
            library, table=self.table, ignore=self.perception_ignore(), reach=self.perception_reach()
        )


def load_scenario(path: str | None = None) -> Scenario:
    """The default scenario, overridden by a YAML file (keys as the dataclass fields)."""
    if not path:
        return Scenario()
    return _checked(
        str(path), lambda: yaml_load_typed(schema=Scenario, filename=str(path), defaults=Scenario())
    )


def scenario_from_text(text: str, where: str = "scenario") -> Scenario:
    """A scenario from YAML text (a file's contents), checked like ``load_scenario``."""
    return _checked(where, lambda: yaml_load_typed(schema=Scenario, data=text, defaults=Scenario()))


def _checked(where: str, load) -> Scenario:
    try:
        sc = load()
    except RuntimeError as e:
        raise MogError(f"{where}: {str(e).splitlines()[0]}") from None
    try:
        check_planner_spec(sc.planner)
        if not sc.robot.reach > 0:
            raise MogError(f"robot.reach must be > 0 m, got {sc.robot.reach}")
    except MogError as e:
        raise MogError(f"{where}: {e}") from None
    return sc


def check_planner_spec(spec: PlannerSpec) -> None:
    """Refuses a planner setting that would only fail once the robot is running."""
    from mog_drake.planning.picking import MODES
    from mog_drake.planning.planner import METHODS

    methods = [m for m in METHODS if m != "single"]  # picking chooses its objects itself
    if spec.method not in methods:
        raise MogError(f"planner.method must be one of {', '.join(methods)}, got {spec.method!r}")
    if spec.mode not in MODES:
        raise MogError(f"planner.mode must be one of {', '.join(MODES)}, got {spec.mode!r}")
    if spec.max_physics_per_group < 0 or spec.n_positions < 1 or spec.n_orientations < 1:
        raise MogError("planner: max_physics_per_group must be >= 0, n_positions and n_orientations >= 1")
    if not 0 <= spec.min_squeeze_margin_deg < 90:
        raise MogError(
            f"planner: min_squeeze_margin_deg must be in [0, 90), got {spec.min_squeeze_margin_deg}"
        )
    if not 0 < spec.hold_s <= 30:
        raise MogError(f"planner: hold_s must be in (0, 30] s, got {spec.hold_s}")
    if not 0 <= spec.settle_window_s <= spec.hold_s:
        raise MogError(
            f"planner: settle_window_s must be in [0, hold_s = {spec.hold_s:g}] s, got {spec.settle_window_s}"
        )
    if not 0 < spec.group_radius <= 0.2:
        raise MogError(f"planner: group_radius must be in (0, 0.2] m, got {spec.group_radius}")
    if spec.grouping not in GROUPINGS:
        raise MogError(f"planner.grouping must be one of {', '.join(GROUPINGS)}, got {spec.grouping!r}")


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


class _GripperState(LeafSystem):
    """Plant state -> (inner jaw opening, its rate)."""

    def __init__(self, plant, left, right, thickness: float):
        super().__init__()
        self._plant = plant
        self._l, self._r, self._t = left, right, thickness
        self._n = plant.num_multibody_states()
        self.DeclareVectorInputPort("state", self._n)
        self.DeclareVectorOutputPort("gripper.state_measured", 2, self._calc)
        self._ctx = plant.CreateDefaultContext()

    def _calc(self, context, output) -> None:
        self._plant.SetPositionsAndVelocities(self._ctx, self.get_input_port(0).Eval(context))
        w = self._r.get_translation(self._ctx) - self._l.get_translation(self._ctx) - self._t
        wd = self._r.get_translation_rate(self._ctx) - self._l.get_translation_rate(self._ctx)
        output.SetFromVector([w, wd])


class _ArmPositions(LeafSystem):
    def __init__(self, n_state_robot: int):
        super().__init__()
        self.DeclareVectorInputPort("state", n_state_robot)
        self.DeclareVectorOutputPort(
            "ur5.position_measured", 6, lambda c, o: o.SetFromVector(self.get_input_port(0).Eval(c)[:6])
        )


def scene_from_spec(spec: SceneSpec):
    from mog_drake.scenes import ClutterParams, Scene, cluttered_scene, row_scene

    if spec.file:
        return Scene.load(spec.file)
    rng = np.random.default_rng(spec.seed)
    if spec.kind == "row":
        return row_scene(spec.row_class, rng)
    if spec.kind == "cluttered":
        return cluttered_scene(
            rng, inventory=spec.inventory, n_objects=spec.n_objects or None, params=ClutterParams()
        )
    raise MogError(f"scene kind must be 'cluttered' or 'row', got {spec.kind!r}")


class StationHandles:
    """What tests and the simulation driver may need beyond the ports."""

    def __init__(self, plant, scene_graph, robot, bodies, scene, gripper_joints):
        self.plant = plant
        self.scene_graph = scene_graph
        self.robot = robot
        self.bodies = bodies
        self.scene = scene
        self.gripper_joints = gripper_joints


def hold_still(scenario: Scenario, station, context) -> None:
    """Fixes the station's inputs: arm at its observe pose, gripper open."""
    station.GetInputPort("ur5.position").FixValue(context, np.array(scenario.robot.home))
    station.GetInputPort("gripper.position").FixValue(context, [0.075])


def render_still(scenario: Scenario, station, context=None):
    """(rgb, depth) of a simulated station at rest: arm at its observe pose, gripper open."""
    ctx = context if context is not None else station.CreateDefaultContext()
    hold_still(scenario, station, ctx)
    rgb = station.GetOutputPort("camera.rgb_image").Eval(ctx).data
    depth = station.GetOutputPort("camera.depth_image").Eval(ctx).data[:, :, 0]
    return rgb, depth


def MakeStation(scenario: Scenario, scene=None, meshcat=None, hardware_clients: dict | None = None):
    """Builds the simulated station (see the module doc for its ports). Returns (diagram,
    handles). The hardware station (``scenario.hardware``) lives in mog_drake.hardware."""
    if scenario.hardware.enabled:
        from mog_drake.hardware.station import MakeHardwareStation

        return MakeHardwareStation(scenario, **(hardware_clients or {}))
    scene = scene or scene_from_spec(scenario.scene)
    gripper = GripperGeometry()
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(scenario.contact.plant_config(), builder)
    x0, x1, y0, y1 = scenario.table
    X_table = RigidTransform([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    add_table(plant, scenario.contact, size=(x1 - x0 + 0.6, y1 - y0 + 0.4), X_WT=X_table)
    add_bin(
        plant,
        scenario.contact,
        RigidTransform([*scenario.bin.center, 0.0]),
        inner=tuple(scenario.bin.inner),
        depth=scenario.bin.depth,
        wall=scenario.bin.wall,
    )

    robot = Parser(plant).AddModels(str(URDF_PATH))[0]
    bx, by, byaw = scenario.robot.base
    plant.WeldFrames(
        plant.world_frame(),
        plant.GetFrameByName("base_link", robot),
        RigidTransform(RotationMatrix.MakeZRotation(byaw), [bx, by, 0.0]),
    )
    # (GetJointActuatorIndices(instance) is empty before Finalize: look the motors up by name.)
    for name in JOINT_NAMES:
        plant.GetJointActuatorByName(f"{name}_motor", robot).set_controller_gains(
            PdControllerGains(p=scenario.robot.kp, d=scenario.robot.kd)
        )
    # The palm hangs off the flange: palm z (up, fingers below) opposite the tool axis.
    palm = plant.AddRigidBody("palm", robot, SpatialInertia.SolidBoxWithMass(0.9, 0.09, 0.06, 0.08))
    plant.WeldFrames(
        plant.GetFrameByName("tool0", robot),
        palm.body_frame(),
        RigidTransform(RotationMatrix.MakeXRotation(np.pi), [0.0, 0.0, FLANGE_TO_PALM]),
    )
    plant.RegisterVisualGeometry(
        palm, RigidTransform([0, 0, 0.045]), Box(0.09, 0.06, 0.09), "palm", np.array([0.2, 0.2, 0.2, 1.0])
    )
    (left, jl), (right, jr) = add_gripper_fingers(
        plant, robot, palm, gripper, scenario.gripper, scenario.contact
    )
    plant.set_gravity_enabled(robot, False)  # a position-controlled arm tracks its command

    bodies = {i: add_prism(plant, scene.shape(i), f"object_{i}", scenario.contact) for i in range(len(scene))}
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

    cam = scenario.camera
    scene_graph.AddRenderer("vtk", MakeRenderEngineVtk(RenderEngineVtkParams()))
    core = RenderCameraCore("vtk", cam.info(), ClippingRange(0.05, 5.0), RigidTransform())
    sensor = builder.AddSystem(
        RgbdSensor(
            scene_graph.world_frame_id(),
            cam.X_WC(),
            ColorRenderCamera(core, False),
            DepthRenderCamera(core, DepthRange(cam.depth_min, cam.depth_max)),
        )
    )
    builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
    builder.ExportOutput(sensor.color_image_output_port(), "camera.rgb_image")
    builder.ExportOutput(sensor.depth_image_32F_output_port(), "camera.depth_image")
    builder.ExportOutput(sensor.label_image_output_port(), "camera.label_image")
    builder.ExportOutput(plant.get_body_poses_output_port(), "sim.body_poses")
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams

        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, MeshcatVisualizerParams())
    diagram = builder.Build()
    diagram.set_name("station")
    return diagram, StationHandles(plant, scene_graph, robot, bodies, scene, (jl, jr))
