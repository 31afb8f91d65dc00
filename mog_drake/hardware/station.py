"""The hardware station: a real UR5 (ur_rtde) and Robotiq 2F-85, and an RGB-D camera source,
exporting the simulated station's port names (see mog_drake.station)."""

from __future__ import annotations

from pydrake.systems.framework import DiagramBuilder

from mog_drake.errors import MogError
from mog_drake.hardware.drivers import (
    CommandLog,
    FaultLatch,
    RealSenseCamera,
    ReplayCamera,
    RobotiqDriver,
    SafetyLimits,
    SafetyMonitor,
    UR5Driver,
)


class HardwareHandles:
    def __init__(self, faults, ur5, gripper, camera, scene=None):
        self.faults, self.ur5, self.gripper, self.camera = faults, ur5, gripper, camera
        self.scene = scene
        self.plant = None


def MakeHardwareStation(scenario, rtde_control=None, rtde_receive=None, gripper_client=None):
    """Builds the hardware station. Clients may be injected (tests); otherwise they connect to
    ``scenario.hardware.robot_ip`` (ur_rtde, the Robotiq URCap socket). A dry run connects to
    nothing and logs every command instead."""
    from mog_drake.station import FLANGE_TO_PALM

    hw = scenario.hardware
    if not hw.robot_ip:
        raise MogError(
            "the hardware station needs an explicit robot address (--robot-ip or hardware.robot_ip)"
        )
    faults = FaultLatch()
    log = CommandLog(hw.command_log) if hw.dry_run else None
    control, receive, gripper = rtde_control, rtde_receive, gripper_client
    if not hw.dry_run:
        if control is None or receive is None:
            try:
                import rtde_control
                import rtde_receive
            except ImportError:
                raise MogError("the UR5 driver needs ur_rtde: pip install 'mog_drake[hardware]'") from None
            try:
                control = control or rtde_control.RTDEControlInterface(hw.robot_ip)
                receive = receive or rtde_receive.RTDEReceiveInterface(hw.robot_ip)
            except RuntimeError as e:
                raise MogError(f"cannot connect to the UR5 at {hw.robot_ip}: {e}") from None
        if gripper is None:
            from mog_drake.hardware.robotiq import RobotiqClient

            gripper = RobotiqClient(hw.robot_ip, hw.gripper_port)
        gripper.activate()
    q_init = list(receive.getActualQ()) if (receive is not None and not hw.dry_run) else scenario.robot.home
    safety = SafetyMonitor(
        SafetyLimits(list(hw.workspace), hw.max_joint_speed), scenario.robot.base, FLANGE_TO_PALM
    )
    builder = DiagramBuilder()
    ur5 = builder.AddNamedSystem(
        "ur5_driver", UR5Driver(control, receive, safety, faults, q_init, hw.servo_period, hw.dry_run, log)
    )
    grip = builder.AddNamedSystem(
        "robotiq_driver",
        RobotiqDriver(
            gripper,
            faults,
            scenario.gripper.force_limit,
            scenario.gripper.close_speed,
            dry_run=hw.dry_run,
            log=log,
        ),
    )
    if hw.camera == "replay":
        camera = builder.AddNamedSystem("camera", ReplayCamera(hw.replay_dir, hw.replay_frame_period))
    elif hw.camera == "realsense":
        camera = builder.AddNamedSystem(
            "camera", RealSenseCamera(scenario.camera.width, scenario.camera.height)
        )
    else:
        raise MogError(f"hardware.camera must be 'realsense' or 'replay', got {hw.camera!r}")
    builder.ExportInput(ur5.GetInputPort("ur5.position"), "ur5.position")
    builder.ExportInput(grip.GetInputPort("gripper.position"), "gripper.position")
    builder.ExportOutput(ur5.GetOutputPort("ur5.position_measured"), "ur5.position_measured")
    builder.ExportOutput(grip.GetOutputPort("gripper.state_measured"), "gripper.state_measured")
    builder.ExportOutput(camera.GetOutputPort("camera.rgb_image"), "camera.rgb_image")
    builder.ExportOutput(camera.GetOutputPort("camera.depth_image"), "camera.depth_image")
    diagram = builder.Build()
    diagram.set_name("hardware_station")
    return diagram, HardwareHandles(faults, ur5, grip, camera)
