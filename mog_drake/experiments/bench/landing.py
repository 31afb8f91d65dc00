"""What the simulated station does when an open plate comes down on an object (`bench landing`).

A target (a large hexagon) and a neighbour 65 mm from it along the grasp's closing axis; the
controller is given one grasp on the target, moved along that axis so that one plate comes down
``overlap`` mm onto the neighbour (a negative overlap: that far clear of it). The station runs
the attempt as a pick run would (no perception, no planner: the decision is fixed) and reports
where the neighbour went and whether the target reached the bin. On the real cell a rigid object
under a descending plate cannot be pressed into the table: the arm stops on it (its force limit)
or the plate rests on it, and the grasp fails. docs/physics.md has the measurement.
"""

from __future__ import annotations

import numpy as np

TARGET, GAP = "large_hexagon", 0.065  # the target; the neighbour's centre this far along -x
NEIGHBOURS = ("thin_bar", "small_yellow_cube", "blue_quad")
OVERLAPS_MM = (-3.0, 1.0, 3.0, 6.0, 10.0)


def landing_attempt(neighbour: str, overlap: float, guard: float = 0.0) -> dict:
    """One attempt on the target whose left plate comes down ``overlap`` (m) onto the
    neighbour, the descent guarded at ``guard`` N (ControllerConfig.guard_force; 0: off)."""
    from pydrake.common.value import AbstractValue
    from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
    from pydrake.systems.framework import DiagramBuilder, EventStatus
    from pydrake.systems.primitives import ConstantValueSource

    from mog_drake.geometry.gripper import GripperGeometry
    from mog_drake.planning.decision import PickDecision
    from mog_drake.scenario import Scenario
    from mog_drake.scenes import Scene, SceneObject, default_library
    from mog_drake.station import MakeStation
    from mog_drake.station.scoring import finger_forces, objects_in_bin
    from mog_drake.systems.messages import Checked, Decision, Perceived
    from mog_drake.systems.pick import connect_arm, make_controller

    lib = default_library()
    x0, y0 = 0.05, -0.05
    scene = Scene(
        [SceneObject(TARGET, x0, y0, 0.0), SceneObject(neighbour, x0 - GAP, y0, 0.0)], lib
    ).validate()
    g = GripperGeometry()
    # Closing axis along x: the left plate spans grasp-frame x in [-w_g/2 - t, -w_g/2]; its
    # outer face comes down ``overlap`` inside the neighbour's nearest edge.
    near = x0 - GAP + lib[neighbour].vertices[:, 0].max()
    grasp = np.array([near - overlap + g.plate_thickness + g.w_g / 2, y0, 0.0])
    sc = Scenario()
    sc.controller.guard_force = guard
    station, h = MakeStation(sc, scene)
    controller = make_controller(sc)  # no arm view: back to the observe pose after the drop
    b = DiagramBuilder()
    b.AddSystem(station)
    b.AddSystem(controller)
    connect_arm(b, station, controller)
    fixed = {
        "decision": Decision(1, PickDecision("grasp", grasp, (0,)), 1),
        "scene": Perceived(counter=10**6),
        "checked": Checked(counter=10**6),
    }
    for port, value in fixed.items():
        src = b.AddSystem(ConstantValueSource(AbstractValue.Make(value)))
        b.Connect(src.get_output_port(), controller.GetInputPort(port))
    sim = Simulator(b.Build())
    ApplySimulatorConfig(sc.simulator, sim)
    ctx = sim.get_mutable_context()
    cctx = controller.GetMyContextFromRoot(ctx)
    pc = h.plant.GetMyContextFromRoot(ctx)
    start = h.plant.EvalBodyPoseInWorld(pc, h.bodies[1]).translation().copy()
    fingers = h.finger_indices()
    peak = [0.0]

    def monitor(root):  # the largest force the fingers put on the neighbour before the jaws close
        if controller.state(controller.GetMyContextFromRoot(root)).mode == "approach":
            on = finger_forces(h.plant, h.scene_graph, pc, fingers, {h.bodies[1].index()})
            peak[0] = max(peak[0], *on.values(), 0.0)
        return EventStatus.DidNothing()

    sim.set_monitor(monitor)
    while ctx.get_time() < 20.0:
        sim.AdvanceTo(ctx.get_time() + 0.1)
        a = controller.state(cctx).attempts
        if a and "end" in a[0] and ctx.get_time() > a[0]["end"] + 1.0:
            break
    stopped = (controller.state(cctx).attempts or [{}])[0].get("stopped")
    X = h.plant.EvalBodyPoseInWorld(pc, h.bodies[1])
    tilt = float(np.degrees(np.arccos(np.clip(X.rotation().matrix()[2, 2], -1.0, 1.0))))
    return {
        "neighbour": neighbour,
        "overlap_mm": round(1e3 * overlap, 1),
        "guard_N": guard,
        "neighbour_moved_mm": round(1e3 * float(np.linalg.norm(X.translation()[:2] - start[:2])), 1),
        "neighbour_tilt_deg": round(tilt),
        "peak_force_N": round(peak[0], 1),
        "stopped_at_N": stopped["force"] if stopped else None,
        "target_in_bin": 0 in objects_in_bin(h.plant, pc, h.bodies, sc),
    }


def bench_landing(progress=None) -> list[dict]:
    """Every neighbour and overlap, the descent unguarded and guarded (the default force)."""
    from mog_drake.config import ControllerConfig

    rows = []
    for guard in (0.0, ControllerConfig().guard_force):
        for n in NEIGHBOURS:
            for o in OVERLAPS_MM:
                rows.append(landing_attempt(n, o * 1e-3, guard))
                if progress is not None:
                    progress.step()
    return rows


def landing_text(rows: list[dict]) -> str:
    lines = []
    for guard in dict.fromkeys(r["guard_N"] for r in rows):
        landed = [r for r in rows if r["overlap_mm"] > 0 and r["guard_N"] == guard]
        clear = [r for r in rows if r["overlap_mm"] <= 0 and r["guard_N"] == guard]
        moved = [r for r in landed if r["neighbour_moved_mm"] > 5 or r["neighbour_tilt_deg"] > 30]
        lines.append(
            (f"guarded at {guard:g} N" if guard else "unguarded")
            + f": a plate came down on the neighbour in {len(landed)} attempts: the target reached the bin in "
            f"{sum(r['target_in_bin'] for r in landed)}, the arm stopped in "
            f"{sum(r['stopped_at_N'] is not None for r in landed)}, the neighbour was pushed over 5 mm or "
            f"tipped over in {len(moved)}; clear of it, {sum(r['target_in_bin'] for r in clear)} of "
            f"{len(clear)} taken, {sum(r['stopped_at_N'] is not None for r in clear)} stopped"
        )
    return "\n".join(lines)
