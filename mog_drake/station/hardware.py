"""The hardware station: a real UR5 (ur_rtde) and Robotiq 2F-85, and an RGB-D camera source,
exporting the simulated station's port contract (`mog_drake.station`)."""

from __future__ import annotations

from pydrake.systems.framework import DiagramBuilder

from mog_drake.camera import camera_intrinsics
from mog_drake.errors import HardwareFault, MogError
from mog_drake.hardware.cameras import RealSenseCamera, ReplayCamera
from mog_drake.hardware.config import ReplaySource
from mog_drake.hardware.robotiq import RobotiqDriver
from mog_drake.hardware.safety import CommandLog, FaultLatch, SafetyLimits, SafetyMonitor, robot_health
from mog_drake.hardware.ur5 import UR5Driver


class HardwareHandles:
    def __init__(self, faults, ur5, gripper, camera, scene=None, connections=None, *, log=None):
        self.faults, self.ur5, self.gripper, self.camera = faults, ur5, gripper, camera
        self.camera_intrinsics = None  # the camera source's own (fx, fy, cx, cy), once built
        self.scene = scene
        self.plant = None
        self._connections = connections if connections is not None else []
        self._log = log
        self.closed = False

    def shutdown(self) -> None:
        """Stops the arm, then closes every connection; safe to call twice and after a fault.
        The gripper is left as it is: whatever it holds stays held."""
        if self.closed:
            return
        self.closed = True
        if self.ur5 is not None:
            self.ur5.stop()
        for conn, methods in self._connections:
            for m in methods:
                try:
                    getattr(conn, m)()
                except Exception:  # a lost connection must not hide the others' closing
                    pass
        if self._log is not None:
            self._log.close()


def MakeHardwareStation(scenario, rtde_control=None, rtde_receive=None, gripper_client=None):
    """Builds the hardware station. Clients may be injected (tests); otherwise they connect to
    ``scenario.hardware.robot_ip`` (ur_rtde, the Robotiq URCap socket). A dry run connects to
    nothing and logs every command instead. A robot that is not connected, running and in a
    normal safety mode, or a gripper that does not activate, refuses to start with one line."""
    hw = scenario.hardware
    if not hw.robot_ip:
        raise MogError(
            "the hardware station needs an explicit robot address (--robot-ip or hardware.robot_ip)"
        )
    faults = FaultLatch()
    log = CommandLog(hw.command_log) if hw.dry_run else None
    control, receive, gripper = rtde_control, rtde_receive, gripper_client
    connections = []
    if not hw.dry_run:
        if control is None or receive is None:
            try:
                import rtde_control
                import rtde_receive
            except ImportError:
                raise MogError("the UR5 driver needs ur_rtde: pip install 'mog_drake[hardware]'") from None
            try:
                receive = receive or rtde_receive.RTDEReceiveInterface(hw.robot_ip)
                control = control or rtde_control.RTDEControlInterface(hw.robot_ip)
            except RuntimeError as e:
                raise HardwareFault(f"UR5: cannot connect to {hw.robot_ip}: {e}") from None
        connections += [(control, ("stopScript", "disconnect")), (receive, ("disconnect",))]
    safety = SafetyMonitor(
        SafetyLimits(
            workspace=list(hw.workspace),
            max_joint_speed=hw.max_joint_speed,
            link_clearance=hw.link_clearance,
            link_box=list(hw.link_box),
            burst_window=hw.burst_window,
        ),
        scenario.robot.base,
        finger_depth=scenario.gripper.finger_height,
    )
    # The handles hold the list itself, so connections opened below are closed too.
    handles = HardwareHandles(faults, None, None, None, connections=connections, log=log)
    try:
        q_init = scenario.robot.home
        if not hw.dry_run:
            if gripper is None:
                from mog_drake.hardware.robotiq import RobotiqClient

                gripper = RobotiqClient(
                    hw.robot_ip,
                    hw.gripper_port,
                    timeout=hw.gripper_timeout,
                    activation_timeout=hw.gripper_activation_timeout,
                    move_timeout=hw.gripper_move_timeout,
                )
            connections.append((gripper, ("close",)))
            reason = robot_health(control, receive)
            if reason:
                raise HardwareFault(f"UR5: not ready: {reason}")
            q_init = list(receive.getActualQ())
            reason = safety.check(q_init)
            if reason:
                raise HardwareFault(f"UR5: the arm starts where it may not be: {reason}")
            gripper.activate()
        diagram = _build(
            scenario,
            hw,
            handles,
            control,
            receive,
            gripper,
            safety=safety,
            faults=faults,
            q_init=q_init,
            log=log,
        )
    except BaseException:
        handles.shutdown()
        raise
    return diagram, handles


def _build(scenario, hw, handles, control, receive, gripper, *, safety, faults, q_init, log):
    """The station's Diagram: the two drivers and the camera source, ports by the contract."""
    builder = DiagramBuilder()
    ur5_driver = UR5Driver(
        control,
        receive,
        safety,
        faults,
        q_init,
        hw.servo_period,
        dry_run=hw.dry_run,
        log=log,
        stale_after=hw.stale_after,
    )
    handles.ur5 = ur5_driver
    ur5 = builder.AddNamedSystem("ur5_driver", ur5_driver)
    grip = builder.AddNamedSystem(
        "robotiq_driver",
        RobotiqDriver(
            gripper,
            faults,
            scenario.gripper.force_limit,
            scenario.gripper.close_speed,
            dry_run=hw.dry_run,
            log=log,
            move_timeout=hw.gripper_move_timeout,
        ),
    )
    if isinstance(hw.camera, ReplaySource):
        camera = builder.AddNamedSystem(
            "camera",
            ReplayCamera(
                hw.camera.dir, hw.camera.frame_period, fallback_intrinsics=camera_intrinsics(scenario.camera)
            ),
        )
    else:
        camera = builder.AddNamedSystem(
            "camera", RealSenseCamera(scenario.camera.width, scenario.camera.height, hw.camera.fps)
        )
    builder.ExportInput(ur5.GetInputPort("ur5.position"), "ur5.position")
    builder.ExportInput(grip.GetInputPort("gripper.position"), "gripper.position")
    builder.ExportOutput(ur5.GetOutputPort("ur5.position_measured"), "ur5.position_measured")
    builder.ExportOutput(ur5.GetOutputPort("ur5.wrist_force"), "ur5.wrist_force")
    builder.ExportOutput(grip.GetOutputPort("gripper.state_measured"), "gripper.state_measured")
    builder.ExportOutput(camera.GetOutputPort("camera.rgb_image"), "camera.rgb_image")
    builder.ExportOutput(camera.GetOutputPort("camera.depth_image"), "camera.depth_image")
    diagram = builder.Build()
    diagram.set_name("hardware_station")
    handles.gripper, handles.camera = grip, camera
    handles.camera_intrinsics = camera.intrinsics
    return diagram
