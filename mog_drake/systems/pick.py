"""The pick-and-place Diagram (station + Perception + Planner + Controller) and its runner."""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder

from mog_drake.camera import camera_pose
from mog_drake.errors import HardwareFault, StationFault, stop_on_signals
from mog_drake.geometry.gripper import OPEN_WIDTH
from mog_drake.planning.planner import GraspPlanner
from mog_drake.scenario import Scenario, scenario_yaml
from mog_drake.station import MakeStation
from mog_drake.station.fault import fault_line, save_fault
from mog_drake.station.ports import PORTS_IN
from mog_drake.station.scoring import AttemptScoring, objects_in_bin, where_left
from mog_drake.station.speed import BinRetirement
from mog_drake.systems.controller import ControllerSystem
from mog_drake.systems.motion import ArmMotion
from mog_drake.systems.pacer import WallClockPacer
from mog_drake.systems.perception import PerceptionSystem
from mog_drake.systems.pick_run import PickRun
from mog_drake.systems.planner import PlannerSystem
from mog_drake.systems.view import ArmView


def make_planner(scenario: Scenario, verifier=None) -> GraspPlanner:
    """The grasp planner of ``scenario.planner``, its physics check ``scenario.verifier`` with
    the station's own jaws (``verifier`` replaces that check, e.g. in tests), its jaws kept
    out of the bin (`Scenario.keep_out`)."""
    from mog_drake.sim.verifier import DrakeVerifier

    spec = scenario.planner
    check = verifier or DrakeVerifier(scenario.verifier, physics=scenario.gripper)
    if spec.robust.samples or spec.robust.screen:
        from mog_drake.planning.robust import RobustVerifier, perturbation_scales
        from mog_drake.scenes.scene import MAX_OBJECTS

        scales = [perturbation_scales(spec.robust, k, MAX_OBJECTS) for k in range(spec.robust.samples)]
        variants = [check.variant(s) if verifier is None else verifier for s in scales]
        check = RobustVerifier(check, variants, spec.robust)
    return GraspPlanner(check, spec.grasp, keep_out=scenario.keep_out())


def make_controller(scenario: Scenario, view: ArmView | None = None) -> ControllerSystem:
    """The Controller of ``scenario``: its arm motions, bin, jaws' timing and settings;
    ``view`` (`arm_view`): when the arm hides none of the table (None: it always returns to
    the observe pose for an image)."""
    g = scenario.gripper
    motion = ArmMotion(
        scenario.robot.base,
        scenario.robot.max_joint_speed,
        scenario.robot.max_joint_acceleration,
        scenario.motion,
        finger_height=g.finger_height,
        finger_clearance=g.finger_clearance,
        q_home=scenario.robot.home,
    )
    return ControllerSystem(
        motion,
        scenario.robot.home,
        scenario.bin.center,
        scenario.bin.depth,
        open_width=OPEN_WIDTH,
        close_time=OPEN_WIDTH / 2 / g.close_speed + scenario.controller.close_margin,
        time_limit=scenario.time_limit,
        config=scenario.controller,
        arm_view=view,
        push_speed=scenario.planner.pushes.speed,
    )


def connect_arm(builder, station, controller) -> None:
    """The station's arm and gripper to the Controller, both ways, by port name."""
    for name in ("ur5.position_measured", "ur5.wrist_force", "gripper.state_measured"):
        builder.Connect(station.GetOutputPort(name), controller.GetInputPort(name))
    for name in PORTS_IN:
        builder.Connect(controller.GetOutputPort(name), station.GetInputPort(name))


def arm_view(scenario: Scenario, intrinsics) -> ArmView:
    """When the arm hides nothing of the perceived table from the camera (`ArmView`)."""
    from mog_drake.sim.ur5 import ArmFrames

    frames = ArmFrames(scenario.robot.base, finger_depth=scenario.gripper.finger_height)
    bx, by, _ = scenario.robot.base
    return ArmView(
        frames,
        [bx, by, 0.0],
        camera_pose(scenario.camera),
        intrinsics,
        scenario.table,
        scenario.perception_ignore(),
    )


@dataclass(frozen=True)
class PickDiagram:
    """The built pick Diagram and its named systems (`handles`: the station's plant, scene and
    devices, as MakeStation returns them)."""

    diagram: Diagram
    station: Diagram
    handles: object
    perception: PerceptionSystem
    planner: PlannerSystem
    controller: ControllerSystem


def MakePickDiagram(
    scenario: Scenario, scene=None, meshcat=None, verifier=None, hardware_clients=None
) -> PickDiagram:
    """Wires the application to a station by port name."""
    station, handles = MakeStation(scenario, scene, meshcat, hardware_clients)
    from mog_drake.scenes import default_library

    library = handles.scene.library if handles.scene is not None else default_library()
    period = scenario.controller.period
    # Jobs may hold up an event (to keep simulated latency exact) in simulation and in a dry
    # run only: on a real arm the servo loop never waits for them.
    block = not (scenario.hardware.enabled and not scenario.hardware.dry_run)
    builder = DiagramBuilder()
    builder.AddNamedSystem("station", station)
    perception = builder.AddNamedSystem(
        "perception",
        PerceptionSystem(
            camera_pose(scenario.camera),
            handles.camera_intrinsics,
            scenario.perceiver(library),
            period,
            latency=scenario.latency,
            block=block,
        ),
    )
    planner_sys = builder.AddNamedSystem(
        "planner",
        PlannerSystem(
            make_planner(scenario, verifier),
            scenario.planner,
            period,
            latency=scenario.latency,
            block=block,
            # A test's verifier (stateless) serves both; the physics check is one per thread.
            ahead_planner=make_planner(scenario, verifier),
        ),
    )
    controller = builder.AddNamedSystem(
        "controller", make_controller(scenario, arm_view(scenario, handles.camera_intrinsics))
    )
    builder.Connect(station.GetOutputPort("camera.rgb_image"), perception.GetInputPort("camera.rgb_image"))
    builder.Connect(
        station.GetOutputPort("camera.depth_image"), perception.GetInputPort("camera.depth_image")
    )
    builder.Connect(controller.GetOutputPort("request"), perception.GetInputPort("request"))
    builder.Connect(perception.GetOutputPort("scene"), planner_sys.GetInputPort("scene"))
    builder.Connect(perception.GetOutputPort("scene"), controller.GetInputPort("scene"))
    builder.Connect(perception.GetOutputPort("checked"), controller.GetInputPort("checked"))
    builder.Connect(controller.GetOutputPort("check"), perception.GetInputPort("check"))
    builder.Connect(planner_sys.GetOutputPort("decision"), controller.GetInputPort("decision"))
    connect_arm(builder, station, controller)
    diagram = builder.Build()
    diagram.set_name("mog_drake_pick")
    return PickDiagram(diagram, station, handles, perception, planner_sys, controller)


def run_pick(
    scenario: Scenario,
    scene=None,
    meshcat=None,
    on_attempt=None,
    verifier=None,
    hardware_clients=None,
    *,
    realtime: bool = False,
    retire_binned: bool = True,
) -> PickRun:
    """Runs the diagram until the table is clear, no grasp is found, or the time limit. In
    simulation each attempt is scored from ground truth (objects in the bin); on hardware there
    is no ground truth and ``picked`` is None. ``retire_binned`` (simulation): objects at rest
    in the bin leave the physics (`BinRetirement`), which keeps a long run fast. ``realtime``:
    paced by the wall clock (`WallClockPacer`), as on hardware.

    On the hardware station the arm is stopped and every connection closed at the end of the
    run, on a fault, on Ctrl-C and on SIGTERM or SIGHUP (`Terminated`); a fault raises
    `HardwareFault` with its one-line reason."""
    t0 = time.perf_counter()
    hw = scenario.hardware
    # A real arm runs at wall pace, whatever the caller asked: its drivers check speed in
    # wall-clock time and would refuse a simulation running flat out.
    realtime = realtime or (hw.enabled and not hw.dry_run)
    # The Diagram's thread waits for the GIL at most this long while a planning job holds it
    # (see mog_drake.systems.jobs).
    switch = sys.getswitchinterval()
    with stop_on_signals():  # SIGTERM and SIGHUP end the run through the finally below
        parts = MakePickDiagram(scenario, scene, meshcat, verifier, hardware_clients)
        diagram = parts.diagram
        if meshcat is not None:
            from mog_drake.station.sim import frame_work_cell

            frame_work_cell(meshcat, scenario)
        try:
            sys.setswitchinterval(0.001)
            return _run(
                scenario, diagram, parts, meshcat, on_attempt, realtime, retire_binned=retire_binned, t0=t0
            )
        except RuntimeError:
            faults = getattr(parts.handles, "faults", None)
            if faults:
                raise HardwareFault(faults.reason) from None
            raise
        finally:
            sys.setswitchinterval(switch)
            if hasattr(parts.handles, "shutdown"):
                parts.handles.shutdown()  # the arm first: a running job may take seconds to end
            parts.perception.shutdown()
            parts.planner.shutdown()


SLEEP_PERIOD = 0.01  # s of simulated time between two looks at which objects may sleep
SEEN_PERIOD = 0.05  # s between two looks at where the camera sees each object (`SeenPoses`)
# s of simulated time after an attempt ends (its jaws open over the bin) before it is scored:
# what it dropped has landed by then. (The arm may go on from the bin at once.)
LANDING_S = 1.0


def _run(scenario, diagram, parts, meshcat, on_attempt, realtime, *, retire_binned, t0) -> PickRun:
    handles = parts.handles
    controller = parts.controller
    sim = Simulator(diagram)
    ApplySimulatorConfig(scenario.simulator, sim)
    pacer = None
    if realtime:  # paced here, never by the Simulator's own catch-up
        sim.set_target_realtime_rate(0.0)
        pacer = WallClockPacer(sim, step=scenario.hardware.servo_period)
    ctx = sim.get_mutable_context()
    ctrl_ctx = controller.GetMyContextFromRoot(ctx)
    scored = handles.plant is not None
    plant_ctx = handles.plant.GetMyContextFromRoot(ctx) if scored else None
    run = PickRun(objects=len(handles.scene) if handles.scene is not None else 0)
    retire = BinRetirement(handles.plant, handles.bodies, scenario) if scored and retire_binned else None
    gone = retire.retired if retire else ()
    # Resting objects out of reach sleep (looked at every SLEEP_PERIOD s of simulated time).
    sleep = handles.sleep(SLEEP_PERIOD) if scored and scenario.sleep else None
    step = SLEEP_PERIOD if sleep else 0.25
    seen = handles.seen_poses(SEEN_PERIOD) if scored else None
    if seen:  # before the first image
        seen.update(ctx)
    sim.Initialize()
    if meshcat is not None:
        meshcat.StartRecording()
    done_attempts = done_pushes = 0
    scoring = AttemptScoring(handles, scenario, parts.perception, ctx, gone) if scored else None
    good = None  # (time, the plant's state) last seen finite: a fault's report says where it began
    while True:
        if scored and np.all(np.isfinite(x := handles.plant.GetPositionsAndVelocities(plant_ctx))):
            good = (ctx.get_time(), x.copy())
        try:
            if pacer is not None:
                pacer.advance_to(ctx.get_time() + step)
            else:
                sim.AdvanceTo(ctx.get_time() + step)
        except RuntimeError:
            if good is None:
                raise
            _fault(scenario, parts, ctx, run, good, sleep, gone=gone, t0=t0)
        if retire:
            retire.update(plant_ctx)
        if sleep:
            sleep.update(ctx, skip=gone)
        if seen:
            seen.update(ctx)
        s = controller.state(ctrl_ctx)
        if scoring:
            scoring.observe(s)
        finished = s.mode == "done" or ctx.get_time() > scenario.time_limit + 30.0
        while done_attempts < len(s.attempts) and "end" in s.attempts[done_attempts]:
            if scored and ctx.get_time() < s.attempts[done_attempts]["end"] + LANDING_S:
                break  # what it dropped is still falling
            a = dict(s.attempts[done_attempts])
            if scoring:
                scoring.score(done_attempts, a)
            else:
                a["picked"] = a["in_bin"] = a["carried"] = None
                # What the gripper lost while this attempt carried it (hardware: OBJ 2 -> 3).
                lost = getattr(handles.gripper, "lost", ())
                a["lost"] = sum(a["start"] <= t <= a["end"] for t in lost)
            run.attempts.append(a)
            done_attempts += 1
            if on_attempt:
                on_attempt(len(run.attempts), a)
        while done_pushes < len(s.pushes) and "end" in s.pushes[done_pushes]:
            run.pushes.append(dict(s.pushes[done_pushes]))
            done_pushes += 1
            if on_attempt:
                on_attempt(done_pushes, run.pushes[-1])
        if finished and done_attempts == sum("end" in a for a in s.attempts):
            run.finished = s.finished or "time limit"
            run.skipped = list(s.skipped)
            break
    if meshcat is not None:
        meshcat.StopRecording()
        meshcat.PublishRecording()
    return _record(run, scenario, parts, ctx, gone, t0)


def _fault(scenario, parts, ctx, run: PickRun, good, sleep, *, gone, t0: float):
    """Ends a run whose station faulted: the record of what it did until then (`_record`, read
    from the last finite state ``good`` = (time, plant state)), that state saved to a file,
    and `StationFault` naming the time and the body."""
    handles = parts.handles
    t = ctx.get_time()
    t_good, x = good
    line = fault_line(handles, x, t, t_good)
    handles.plant.SetPositionsAndVelocities(handles.plant.GetMyMutableContextFromRoot(ctx), x)
    run.finished = "station fault"
    run.skipped = list(parts.controller.state(parts.controller.GetMyContextFromRoot(ctx)).skipped)
    run = _record(run, scenario, parts, ctx, gone, t0)
    name = f"seed{getattr(scenario.scene, 'seed', 0)}-{scenario.planner.mode}-t{t:.3f}"
    asleep = sleep.asleep if sleep else ()
    try:
        path = save_fault(handles, scenario_yaml(scenario), x, t_good, asleep, gone, line=line, name=name)
        where = f"; its last finite state is saved in {path}"
    except OSError as e:
        path, where = None, f"; its last finite state could not be saved ({e.strerror or e})"
    raise StationFault(line + where, run=run, path=path) from None


def _record(run: PickRun, scenario, parts, ctx, gone, t0: float) -> PickRun:
    """``run`` completed from the station and the controller: what is in the bin and where the
    rest lies (simulation only), and the times (``t0``: the run's start, perf_counter)."""
    handles, controller = parts.handles, parts.controller
    if handles.plant is not None:
        plant_ctx = handles.plant.GetMyContextFromRoot(ctx)
        in_bin = objects_in_bin(handles.plant, plant_ctx, handles.bodies, scenario, gone)
        run.in_bin = len(in_bin)
        run.left = where_left(handles.plant, plant_ctx, handles.bodies, scenario, in_bin)
        run.shapes = [o.shape for o in handles.scene.objects]
    run.sim_time = ctx.get_time()
    run.wall_time = time.perf_counter() - t0
    s = controller.state(controller.GetMyContextFromRoot(ctx))
    run.robot_time, run.wait_perception, run.wait_planning = s.robot_time, s.wait_perception, s.wait_planning
    run.cycle_time = (s.t_end if s.t_end is not None else ctx.get_time()) - (s.t_first or 0.0)
    run.perception_time = parts.perception.wall_total(parts.perception.GetMyContextFromRoot(ctx))
    run.retakes = s.retakes
    run.push_time = s.push_time
    return run
