"""The station: the simulated one (a MultibodyPlant with the UR5, the gripper, the table, the
bin, the prisms and an overhead RGB-D camera) or the hardware one, behind one port contract.

`MakeStation(scenario)` returns (diagram, handles). Both stations export the same ports, so an
application Diagram is wired by name only and never knows which one it has:

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

World frame = table frame: origin at the centre of the table top, z up. Beside the ports,
``handles.camera_intrinsics`` is (fx, fy, cx, cy) of the images the camera source gives, pixel
centres at integer coordinates: the rendered camera's (`rendered_intrinsics`), a RealSense's
read from the device, or those recorded with replayed frames.

* `mog_drake.station.sim`: the simulated station (`MakeSimStation`).
* `mog_drake.station.hardware`: the hardware station (`MakeHardwareStation`).
* `mog_drake.station.scoring`: ground-truth scoring, outside the Diagram.
"""

from mog_drake.scenario import Scenario, check_scenario
from mog_drake.station.hardware import MakeHardwareStation
from mog_drake.station.ports import PORTS_IN, PORTS_OUT, SIM_ONLY_PORTS
from mog_drake.station.sim import (
    MakeSimStation,
    StationHandles,
    fastest_motion,
    hold_still,
    render_still,
    rendered_intrinsics,
    scene_from_spec,
    still_station,
)

__all__ = [
    "PORTS_IN",
    "PORTS_OUT",
    "SIM_ONLY_PORTS",
    "MakeStation",
    "MakeSimStation",
    "MakeHardwareStation",
    "StationHandles",
    "hold_still",
    "render_still",
    "still_station",
    "fastest_motion",
    "rendered_intrinsics",
    "scene_from_spec",
]


def MakeStation(
    scenario: Scenario, scene=None, meshcat=None, hardware_clients: dict | None = None, board=None
):
    """The station of ``scenario``: the hardware one if ``scenario.hardware.enabled`` (clients
    may be injected, e.g. test fakes), else the simulated one (``scene`` replaces the
    scenario's own objects). The scenario is checked first (`check_scenario`): a station built
    in code gets the same refusals as one loaded from a file."""
    check_scenario(scenario)
    if scenario.hardware.enabled:
        return MakeHardwareStation(scenario, **(hardware_clients or {}))
    return MakeSimStation(scenario, scene, meshcat, board)
