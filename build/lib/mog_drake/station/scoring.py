"""Scoring from the simulated station's ground truth: what is in the bin, where the rest lies.
It stays outside the application Diagram: the application never reads ground truth."""

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialVelocity

from mog_drake.camera import camera_sees
from mog_drake.perception import within_reach
from mog_drake.scenario import Scenario


def objects_in_bin(plant, plant_context, bodies, scenario: Scenario, retired=()) -> list[int]:
    """Scoring only (ground truth): objects whose centre lies inside the bin's walls, plus
    those already retired from it (see `BinRetirement`)."""
    cx, cy = scenario.bin.center
    hx, hy = scenario.bin.inner[0] / 2, scenario.bin.inner[1] / 2
    out = []
    for i, b in bodies.items():
        if i in retired:
            out.append(i)
            continue
        p = plant.EvalBodyPoseInWorld(plant_context, b).translation()
        if abs(p[0] - cx) <= hx and abs(p[1] - cy) <= hy and p[2] < scenario.bin.depth + 0.05:
            out.append(i)
    return out


class BinRetirement:
    """Simulation speed, not physics: an object at rest in the bin is taken out of the scene.

    A pile in the bin is the costliest contact in the station (`mog-drake bench station`: 33
    prisms piled in the bin cost over 4x the same 33 on the table, and close to 20x the
    station once the pile is retired), and
    nothing the robot does depends on it: the bin is outside the camera's view and the robot
    only drops objects into it. Retired objects are parked far above the station, each in its
    own spot, put back there with zero velocity at every check (they fall freely in between),
    and counted in the bin for good. The pile is gone, so a later drop lands on the bin floor;
    a Meshcat replay shows retired objects leave the bin."""

    PARK = np.array([20.0, 20.0, 50.0])  # m, far from everything, above the table's half-space

    def __init__(self, plant, bodies, scenario: Scenario, rest_speed: float = 0.02):
        self.plant, self.bodies, self.scenario = plant, bodies, scenario
        self.rest_speed = rest_speed
        self.retired: list[int] = []

    def update(self, plant_context) -> None:
        plant = self.plant
        for i in objects_in_bin(plant, plant_context, self.bodies, self.scenario, self.retired):
            if i in self.retired:
                continue
            v = plant.EvalBodySpatialVelocityInWorld(plant_context, self.bodies[i])
            if np.linalg.norm(v.translational()) < self.rest_speed:
                self.retired.append(i)
        for k, i in enumerate(self.retired):
            X = RigidTransform(self.PARK + [0.3 * k, 0.0, 0.0])
            plant.SetFreeBodyPose(plant_context, self.bodies[i], X)
            plant.SetFreeBodySpatialVelocity(plant_context, self.bodies[i], SpatialVelocity.Zero())


def where_left(plant, plant_context, bodies, scenario: Scenario, in_bin) -> dict:
    """Scoring only (ground truth): where each object outside the bin is."""
    x0, x1, y0, y1 = scenario.table
    reach = scenario.perception_reach()
    out = {}
    for i, b in bodies.items():
        if i in in_bin:
            continue
        p = plant.EvalBodyPoseInWorld(plant_context, b).translation()
        if p[2] < -0.02:
            where = "off the table"
        elif (
            x0 <= p[0] <= x1
            and y0 <= p[1] <= y1
            and camera_sees(scenario.camera, p)
            and within_reach(p[0], p[1], reach)
        ):
            where = "in view"
        else:
            where = "out of view"
        out[int(i)] = (where, [round(float(v), 3) for v in p])
    return out


def station_state(handles, x, sleep, retired, t: float, t_good: float | None = None) -> str:
    """The station's last finite state ``x`` (the plant's positions and velocities, at
    ``t_good``) in a line for a fault's report: the fault's time, the fastest bodies and where
    they were, and what was asleep or retired."""
    plant = handles.plant
    q, v = x[: plant.num_positions()], x[plant.num_positions() :]
    speeds = []
    for i, body in handles.bodies.items():
        start, at = body.floating_velocities_start_in_v(), body.floating_positions_start()
        p = q[at + 4 : at + 7]  # after the quaternion: the origin's position
        speeds.append((float(np.linalg.norm(v[start + 3 : start + 6])), i, p))
    speeds.sort(key=lambda s: -np.inf if np.isnan(s[0]) else -s[0])  # non-finite first
    fastest = ", ".join(
        f"object {i} at {s:.3g} m/s at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m" for s, i, p in speeds[:3]
    )
    asleep = sorted(sleep.asleep) if sleep else []
    arm = np.abs(plant.GetVelocitiesFromArray(handles.robot, v)[:6]).max()  # the UR5's six joints
    when = "" if t_good is None else f" (t = {t_good:.3f} s)"
    return (
        f"(station at t = {t:.3f} s, its last finite state{when}: fastest {fastest}; "
        f"arm joint speeds up to {arm:.3g} rad/s; asleep {asleep}; retired {sorted(retired)})"
    )
