"""The station's port contract: the names both stations export, by which the application
Diagram is wired (see `mog_drake.station`)."""

PORTS_IN = ("ur5.position", "gripper.position")
PORTS_OUT = (
    "ur5.position_measured",
    "ur5.wrist_force",
    "gripper.state_measured",
    "camera.rgb_image",
    "camera.depth_image",
)
SIM_ONLY_PORTS = ("camera.label_image", "sim.body_poses")
