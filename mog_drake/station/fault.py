"""A simulated station's physics fault: the one line that names it, and its last finite state
saved to a file (`StationFault`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

FAULT_DIR = Path("out/station_faults")


def fastest_objects(handles, x) -> list[tuple[float, int, np.ndarray]]:
    """(speed m/s, object id, position m) of every object in the plant state ``x``
    (positions then velocities), fastest first (non-finite speeds first of all)."""
    plant = handles.plant
    q, v = x[: plant.num_positions()], x[plant.num_positions() :]
    out = []
    for i, body in handles.bodies.items():
        start, at = body.floating_velocities_start_in_v(), body.floating_positions_start()
        out.append((float(np.linalg.norm(v[start + 3 : start + 6])), i, q[at + 4 : at + 7]))
    out.sort(key=lambda s: -np.inf if np.isnan(s[0]) else -s[0])
    return out


def fault_line(handles, x, t: float, t_good: float) -> str:
    """The fault at time ``t`` in one line: the body moving fastest in the last finite state
    ``x`` (at ``t_good``), its speed and where it was."""
    speed, i, p = fastest_objects(handles, x)[0]
    shape = handles.scene.objects[i].shape
    return (
        f"the simulated station failed at t = {t:.3f} s: object {i} ({shape}) moved at {speed:.3g} m/s "
        f"at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m in its last finite state (t = {t_good:.3f} s)"
    )


def save_fault(
    handles, scenario_yaml: str, x, t_good: float, asleep, retired, *, line: str, name: str
) -> Path:
    """The station's last finite state saved for a replay (`numpy.load`): the plant's
    positions and velocities ``x`` at ``t_good``, the objects asleep and retired, the scene
    and scenario as YAML, and the fault's line. Returns the file's path
    (``out/station_faults/NAME.npz``)."""
    FAULT_DIR.mkdir(parents=True, exist_ok=True)
    path = FAULT_DIR / f"{name}.npz"
    np.savez(
        path,
        x=np.asarray(x),
        t=t_good,
        asleep=np.array(sorted(asleep), int),
        retired=np.array(sorted(retired), int),
        scene=handles.scene.to_yaml(),
        scenario=scenario_yaml,
        fault=line,
    )
    return path
