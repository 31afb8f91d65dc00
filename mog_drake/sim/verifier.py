"""CheckGraspSuccess() in Drake: close the gripper at u, lift under gravity, see what stays.

The gripper is an arm-less gantry (x, y, z, yaw; gravity off) with two force-limited finger
plates. For a (scene, group) the plant is built once, holding the group and every object the
closing jaws could reach; each grasp then only resets the context, so a planner that checks
many candidates of one group pays the build once.
"""

import time
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.multibody.plant import AddMultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, EventStatus

from mog_drake.errors import MogError, terminating
from mog_drake.geometry import GripperGeometry, objects_at_grasp, objects_in_reach
from mog_drake.geometry.conditions import jaw_collision_free
from mog_drake.geometry.push import near_path, push_duration
from mog_drake.planning.protocol import GraspResult
from mog_drake.sim.models import (
    GripperPhysics,
    add_gantry_gripper,
    add_prism,
    add_table,
    filter_gripper_self_collisions,
    pose_to_transform,
)
from mog_drake.sim.scripts import GraspScript, PushScript
from mog_drake.sim.verifier_config import VerifierConfig


@dataclass
class PushResult:
    """Where a push leaves the objects: ``scene`` (the simulated objects at their new planar
    poses, every other object where it was), ``moved`` (id -> distance its centre moved, m),
    ``error`` (empty when the push ran as intended: an object tipped over, left the table or
    a solver fault is an error, and then ``scene`` is None)."""

    scene: object = None
    moved: dict = field(default_factory=dict)
    error: str = ""
    sim_time: float = 0.0
    wall_time: float = 0.0


class _GroupSim:
    """A built diagram for one (scene, group): plant, script, simulator, default context."""

    def __init__(self, scene, ids: list[int], verifier: "DrakeVerifier", script_type=None):
        gripper, config, physics = verifier.gripper, verifier.config, verifier.physics
        t0 = time.perf_counter()
        builder = DiagramBuilder()
        plant, scene_graph = AddMultibodyPlant(config.contact.plant, builder)
        x0, x1, y0, y1 = scene.table
        add_table(plant, config.contact, size=(x1 - x0 + 0.4, y1 - y0 + 0.4))
        self.bodies = {}
        for i in ids:
            self.bodies[i] = add_prism(
                plant, scene.shape(i), f"object_{i}", config.contact, *verifier.scales(i)
            )
        self.gripper = add_gantry_gripper(plant, gripper, physics, config.contact)
        plant.Finalize()
        filter_gripper_self_collisions(
            plant,
            scene_graph,
            [
                plant.GetBodyByName(n, self.gripper.instance)
                for n in ("carriage_x", "carriage_y", "carriage_z", "palm", "left_finger", "right_finger")
            ],
        )
        self.script = builder.AddSystem((script_type or GraspScript)(gripper, config, physics))
        builder.Connect(
            self.script.get_output_port(), plant.get_desired_state_input_port(self.gripper.instance)
        )
        self.meshcat = meshcat = verifier.meshcat
        if meshcat is not None:
            from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams

            MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, MeshcatVisualizerParams())
        self.diagram = builder.Build()
        self.plant = plant
        self.simulator = Simulator(self.diagram)
        self.context = self.simulator.get_mutable_context()
        self.plant_context = plant.GetMyMutableContextFromRoot(self.context)
        self.script_context = self.script.GetMyMutableContextFromRoot(self.context)
        self.default_context = self.context.Clone()
        self.poses = {i: scene.objects[i].pose for i in ids}
        # Highest point of each prism above its body origin (at its base), however it is
        # tilted: the farthest any point of it lies from that origin.
        self.heights = {i: scene.shape(i).reach for i in ids}
        self.table = scene.table
        self.build_time = time.perf_counter() - t0


class DrakeVerifier:
    """The physics grasp check (implements the `Verifier` protocol): ``config`` the check's
    own settings, ``gripper`` the jaws' geometry and ``physics`` their dynamics (the station's
    own, so the check and the station cannot drift apart).

    ``check(scene, group, grasp)`` returns a `GraspResult`. Faults are results: a solver
    failure, a non-finite state, an object leaving the table or a run past the CPU budget
    (of the calling thread) gives success=False with an error saying what happened.
    """

    def __init__(
        self,
        config: VerifierConfig | None = None,
        gripper: GripperGeometry | None = None,
        physics: GripperPhysics | None = None,
        meshcat=None,
        objects: dict | None = None,
    ):
        self.config = config or VerifierConfig()
        self.gripper = gripper or GripperGeometry()
        self.physics = physics or GripperPhysics()
        self.meshcat = meshcat
        # Friction and mass scales of the objects, by object id ("friction", "mass": arrays):
        # the model's own values (1) when None.
        self.objects = objects
        self.config.check()
        self._sims: dict = {}  # key -> _GroupSim, least recently used first
        self._sim: _GroupSim | None = None

    def scales(self, i: int) -> tuple[float, float]:
        """Object ``i``'s friction and mass scales in this check's world."""
        if self.objects is None:
            return 1.0, 1.0
        return float(self.objects["friction"][i]), float(self.objects["mass"][i])

    def variant(self, scales: dict) -> "DrakeVerifier":
        """The same check in a world of other friction and mass (`planning.robust`): objects'
        by id, the jaws' (``finger``) and the table's scaled."""
        c = self.config.contact
        contact = replace(c, mu_finger=c.mu_finger * scales["finger"], mu_table=c.mu_table * scales["table"])
        return DrakeVerifier(
            replace(self.config, contact=contact), self.gripper, self.physics, objects=scales
        )

    SIMS_KEPT = 8  # built plants kept for reuse ("grasp" bodies: candidates of a group share sets)

    def _sim_for(self, scene, group, grasp=None) -> tuple[_GroupSim, bool]:
        if self.config.bodies == "grasp" and grasp is not None:
            ids = objects_at_grasp(scene, group, grasp, self.gripper, self.config.grasp_margin)
        else:
            ids = objects_in_reach(scene, group, self.gripper, self.config.reach_margin)
        key = (
            tuple((scene.objects[i].shape, scene.objects[i].pose) for i in ids),
            tuple(ids),
            id(scene.library),
        )
        if key in self._sims:
            self._sim = self._sims[key] = self._sims.pop(key)  # most recently used last
            return self._sim, False
        self._sim = _GroupSim(scene, ids, self)
        self._sims[key] = self._sim
        while len(self._sims) > self.SIMS_KEPT:
            self._sims.pop(next(iter(self._sims)))
        return self._sim, True

    @property
    def last_build_time(self) -> float:
        """Seconds the current plant took to build (0 before the first check)."""
        return 0.0 if self._sim is None else self._sim.build_time

    SETTLE_PERIOD = 0.01  # s between two looks at the objects' speeds (settle_window)
    PUSH_SETTLE = 0.3  # s the objects come to rest after a push, before their poses are read
    PUSH_REACH = 0.05  # m around the pushed object's path: objects it can move

    def push(self, scene, push, speed: float = 0.1) -> PushResult:
        """Simulates ``push`` (`mog_drake.geometry.push.Push`) with the closed jaws at a mean
        ``speed`` (m/s), and returns where it leaves the objects (`PushResult`)."""
        from mog_drake.scenes import SceneObject

        t0 = time.perf_counter()
        polys = scene.polygons()
        reach = push.length + polys.radii[push.target] * 2
        near = near_path(polys, push.start, push.direction, reach, self.PUSH_REACH)
        ids = sorted(set(near.tolist()) | {push.target})
        sim = _GroupSim(scene, ids, self, PushScript)
        plant, pc = sim.plant, sim.plant_context
        duration = push_duration(push, speed)
        sim.script.set_push(sim.script_context, push, duration)
        for i, body in sim.bodies.items():
            plant.SetFloatingBaseBodyPoseInWorldFrame(pc, body, pose_to_transform(*sim.poses[i]))
        j = sim.gripper.joints
        f = self.gripper.plate_thickness / 2
        for joint, q in zip((j[0], j[1], j[2], j[4], j[5]), (*push.start, sim.script.z_grasp, -f, f)):
            joint.set_translation(pc, q)
        j[3].set_angle(pc, push.yaw)
        cpu_deadline = time.thread_time() + self.config.cpu_budget

        def monitor(root_context):
            if time.thread_time() > cpu_deadline:
                return EventStatus.Failed(None, f"CPU budget of {self.config.cpu_budget:g} s exceeded")
            return EventStatus.Succeeded()

        sim.simulator.set_monitor(monitor)
        try:
            sim.simulator.Initialize()
            sim.simulator.AdvanceTo(duration + self.PUSH_SETTLE)
        except Exception as e:
            terminating()  # a stop signal raised inside a Drake callback is no physics error
            msg = str(e).splitlines()[0] if str(e) else type(e).__name__
            return PushResult(error=f"simulation failed: {msg}", wall_time=time.perf_counter() - t0)
        finally:
            sim.simulator.clear_monitor()
        objects, moved, errors = list(scene.objects), {}, []
        x0, x1, y0, y1 = scene.table
        for i, body in sim.bodies.items():
            X = plant.EvalBodyPoseInWorld(pc, body)
            p, R = X.translation(), X.rotation().matrix()
            if not np.all(np.isfinite(p)):
                errors.append(f"object {i}: non-finite pose")
            elif R[2, 2] < np.cos(np.radians(10)):
                errors.append(f"object {i} tipped over")
            elif not (x0 <= p[0] <= x1 and y0 <= p[1] <= y1):
                errors.append(f"object {i} left the table")
            else:
                o = scene.objects[i]
                objects[i] = SceneObject(
                    o.shape, float(p[0]), float(p[1]), float(np.arctan2(R[1, 0], R[0, 0]))
                )
                moved[i] = float(np.hypot(p[0] - o.x, p[1] - o.y))
        wall = time.perf_counter() - t0
        t_sim = sim.context.get_time()
        if errors:
            return PushResult(moved=moved, error="; ".join(errors), sim_time=t_sim, wall_time=wall)
        after = replace(scene, objects=objects, group=None)
        return PushResult(after, moved, "", t_sim, wall)

    def check(self, scene, group, grasp) -> GraspResult:
        t0 = time.perf_counter()
        grasp = np.asarray(grasp, dtype=float)
        if grasp.shape != (3,) or not np.all(np.isfinite(grasp)):
            return GraspResult(
                False, error=f"grasp must be three finite numbers, got {grasp.tolist()}", complete=False
            )
        # Open jaws placed inside an object start in penetration, and the contact's push-out
        # can "lift" it: such a grasp is no grasp (the planner only simulates collision-free
        # candidates; a grasp given by hand may not be).
        if not jaw_collision_free(scene.polygons(), grasp[None, :], self.gripper)[0]:
            return GraspResult(
                False,
                wall_time=time.perf_counter() - t0,
                error="the open jaws start in collision with an object",
                complete=False,
            )
        sim, built = self._sim_for(scene, group, grasp)
        result = self._run(sim, group, grasp, t0)
        result.built, result.bodies = built, len(sim.bodies)
        return result

    def _run(self, sim: _GroupSim, group, grasp, t0: float) -> GraspResult:
        self._place(sim, grasp)
        timeline = self.config.timeline(self.gripper, self.physics)
        watch = _Watch(self, sim, group, timeline)
        sim.simulator.set_monitor(watch)
        if sim.meshcat is not None:
            sim.meshcat.StartRecording()
        try:
            sim.simulator.Initialize()
            sim.simulator.AdvanceTo(timeline["end"])
        except Exception as e:  # solver failure or a monitor abort
            terminating()  # a stop signal raised inside a Drake callback is no physics error
            msg = (
                watch.error or f"simulation failed: {str(e).splitlines()[0] if str(e) else type(e).__name__}"
            )
            return GraspResult(
                False,
                sim_time=sim.context.get_time(),
                wall_time=time.perf_counter() - t0,
                error=msg,
                complete=False,
            )
        finally:
            sim.simulator.clear_monitor()
            if sim.meshcat is not None:
                sim.meshcat.StopRecording()
                sim.meshcat.PublishRecording()
        return self._verdict(sim, group, t0, watch.early)

    def _place(self, sim: _GroupSim, grasp) -> None:
        """The check's start: the objects where the scene has them, the jaws open at the
        grasp's pose and height."""
        plant, pc = sim.plant, sim.plant_context
        sim.context.SetTimeStateAndParametersFrom(sim.default_context)
        half = self.gripper.opening / 2  # the jaws start open
        sim.script.set_grasp(sim.script_context, grasp)
        for i, body in sim.bodies.items():
            plant.SetFloatingBaseBodyPoseInWorldFrame(pc, body, pose_to_transform(*sim.poses[i]))
        j = sim.gripper.joints
        z0 = sim.script.z_grasp
        for joint, q in zip((j[0], j[1], j[2], j[4], j[5]), (grasp[0], grasp[1], z0, -half, half)):
            joint.set_translation(pc, q)
        j[3].set_angle(pc, grasp[2])  # yaw

    def _verdict(self, sim: _GroupSim, group, t0: float, early: str = "") -> GraspResult:
        cfg, plant, pc = self.config, sim.plant, sim.plant_context
        q = plant.GetPositions(pc)
        wall = time.perf_counter() - t0
        t = sim.context.get_time()
        if not np.all(np.isfinite(q)):
            return GraspResult(
                False, sim_time=t, wall_time=wall, error="non-finite state at the end", complete=False
            )
        x0, x1, y0, y1 = sim.table
        lifted, errors = [], []
        threshold = cfg.lifted_height
        for i, body in sim.bodies.items():
            p = plant.EvalBodyPoseInWorld(pc, body).translation()
            if p[2] < -0.02 or not (x0 - 0.2 <= p[0] <= x1 + 0.2 and y0 - 0.2 <= p[1] <= y1 + 0.2):
                errors.append(f"object {i} left the table (at {np.round(p, 3).tolist()})")
            elif p[2] > threshold:
                lifted.append(i)
        jl, jr = sim.gripper.joints[4], sim.gripper.joints[5]
        opening = jr.get_translation(pc) - jl.get_translation(pc) - self.gripper.plate_thickness
        if errors:
            return GraspResult(False, lifted, opening, t, wall, error="; ".join(errors), complete=False)
        success = not early and all(int(i) in lifted for i in group)
        return GraspResult(success, lifted, float(opening), t, wall, complete=not early)


class _Watch:
    """The check's monitor, looking at the state every SETTLE_PERIOD of simulated time: it
    fails the run on a non-finite state or past the CPU budget, and ends it once every lifted
    object has held still over ``hold_window``, once an object of the group is left on the
    table (``early_exit``), or once every object settled (``settle_window``)."""

    def __init__(self, verifier: DrakeVerifier, sim: _GroupSim, group, timeline: dict):
        self.cfg, self.plant, self.period = verifier.config, sim.plant, verifier.SETTLE_PERIOD
        self.timeline = timeline
        self.cpu_deadline = time.thread_time() + self.cfg.cpu_budget
        self.error = self.early = ""
        self.group_bodies = [(int(i), sim.bodies[int(i)], sim.heights[int(i)]) for i in group]
        self.z_joint = sim.gripper.joints[2]
        self.finger_h = verifier.physics.finger_height
        self.watched = [(body, sim.heights[i]) for i, body in sim.bodies.items()]  # (body, farthest point)
        self.lifted_z = self.cfg.lifted_height
        self.settle_samples: list = []
        self.settle_next = timeline["lift1"]
        self.still_samples: list = []
        self.still_next = timeline["lift1"]
        self.look_next = 0.0

    def __call__(self, root_context):
        cfg, plant = self.cfg, self.plant
        t = root_context.get_time()
        if t < self.look_next - 1e-9:  # Python looks at the state every SETTLE_PERIOD
            return EventStatus.Succeeded()
        self.look_next = t + self.period
        ctx = plant.GetMyContextFromRoot(root_context)
        q = plant.GetPositions(ctx)
        if not np.all(np.isfinite(q)):
            self.error = f"non-finite state at t = {t:.3f} s"
            return EventStatus.Failed(None, self.error)
        if time.thread_time() > self.cpu_deadline:
            self.error = f"CPU budget of {cfg.cpu_budget:g} s exceeded at t = {t:.3f} s"
            return EventStatus.Failed(None, self.error)
        if cfg.hold_window > 0 and t >= self.still_next - 1e-9 and self._held_still(ctx, t):
            return EventStatus.ReachedTermination(None, "every lifted object held still in the hold")
        if cfg.early_exit and t > self.timeline["lift0"]:
            finger_bottom = self.z_joint.get_translation(ctx) - self.finger_h
            left = [
                i
                for i, body, top in self.group_bodies
                if finger_bottom > plant.EvalBodyPoseInWorld(ctx, body).translation()[2] + top
            ]
            k = cfg.report_partial_lifts
            if left and (k <= 0 or len(self.group_bodies) - len(left) < k):
                self.early = f"object(s) {left} left on the table"
                return EventStatus.ReachedTermination(None, self.early)
        if cfg.settle_window > 0 and self._settled(ctx, t):
            return EventStatus.ReachedTermination(None, "every object settled in the hold")
        return EventStatus.Succeeded()

    def _settled(self, ctx, t) -> bool:
        """Whether, over the last settle_window of the hold, the fastest lifted object's
        speed averaged under settle_speed (a mean: contact jitter spikes for a step or two).
        Objects below the lifted height are left out: with the jaws still in the air, one
        pushed aside on the table can slide on but never count as lifted."""
        cfg, plant = self.cfg, self.plant
        if t < self.settle_next:
            return False
        self.settle_next = t + self.period
        fastest = 0.0
        for body, r in self.watched:
            if plant.EvalBodyPoseInWorld(ctx, body).translation()[2] <= self.lifted_z:
                continue  # on the table: nothing in the hold can lift it now
            V = plant.EvalBodySpatialVelocityInWorld(ctx, body)
            fastest = max(fastest, np.linalg.norm(V.translational()) + r * np.linalg.norm(V.rotational()))
        s = self.settle_samples
        s.append((t, fastest))
        while len(s) > 1 and t - s[1][0] >= cfg.settle_window - 1e-9:
            s.pop(0)
        return t - s[0][0] >= cfg.settle_window - 1e-9 and np.mean([v for _, v in s]) < cfg.settle_speed

    def _held_still(self, ctx, t) -> bool:
        """Whether, over the last hold_window of the hold, no object above the lifted height
        moved more than hold_drift (sampled every SETTLE_PERIOD)."""
        cfg = self.cfg
        p = np.array([self.plant.EvalBodyPoseInWorld(ctx, body).translation() for body, _ in self.watched])
        s = self.still_samples
        s.append((t, p))
        while len(s) > 1 and t - s[1][0] >= cfg.hold_window - 1e-9:
            s.pop(0)
        if t - s[0][0] < cfg.hold_window - 1e-9:
            return False
        up = p[:, 2] > self.lifted_z
        return bool(np.all(np.linalg.norm(p - s[0][1], axis=1)[up] < cfg.hold_drift))


def row_verifier(meshcat=None) -> DrakeVerifier:
    """The physics check of the paper's row experiments (models/row_check.yaml), with its
    gripper."""
    from mog_drake.scenario import load_scenario

    sc = load_scenario("row_check")
    return DrakeVerifier(sc.verifier, physics=sc.gripper, meshcat=meshcat)


def verify_one(scenario, scene, group, grasp, force: float | None = None, meshcat=None) -> GraspResult:
    """One grasp checked in physics with ``scenario``'s verifier and gripper (``force``: the
    grip force limit per jaw instead, N), shown in ``meshcat`` if given."""
    physics = scenario.gripper
    if force is not None:
        if not 0 < force <= 235:
            raise MogError(f"--force must be in (0, 235] N (the 2F-85's range), got {force}")
        physics = replace(physics, force_limit=force)
    return DrakeVerifier(scenario.verifier, physics=physics, meshcat=meshcat).check(scene, group, grasp)
