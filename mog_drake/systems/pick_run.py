"""A pick run's record (`PickRun`: its attempts, pushes, times and what it left) and its text:
the log line of each attempt and the summary of a run."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from mog_drake.scenario import Scenario


def dropped_in_transit(a: dict) -> int:
    """Objects an attempt lost on the way to the bin: in simulation those lifted (in the air as
    the arm left for the bin) but not in the bin when it ended; on hardware the holds the
    gripper lost (OBJ 2 -> 3)."""
    if a.get("carried") is not None:
        return max(len(a["carried"]) - (a.get("picked") or 0), 0)
    return int(a.get("lost") or 0)


@dataclass
class PickRun:
    objects: int
    attempts: list[dict] = field(default_factory=list)
    skipped: list[dict] = field(default_factory=list)  # planned grasps the arm could not reach
    in_bin: int = 0
    sim_time: float = 0.0
    wall_time: float = 0.0
    finished: str = ""
    # Simulated time (s), from the controller: the arm moving or the gripper acting; the arm
    # idle waiting for a scene, and for a decision; from the first request to the end.
    robot_time: float = 0.0
    wait_perception: float = 0.0
    wait_planning: float = 0.0
    cycle_time: float = 0.0
    perception_time: float = 0.0  # wall time of the perception jobs (s)
    retakes: int = 0  # decisions dropped: the table changed after their image
    pushes: list[dict] = field(default_factory=list)  # push-mog: the pushes made, in order
    push_time: float = 0.0  # robot time of the pushes (s)
    # Simulation only: where each object not in the bin ended, {id: (where, [x, y, z])} with
    # where "in view" (on the table, inside the perceived region, the camera's image and the
    # arm's reach), "out of view" (on the table, outside them) or "off the table".
    left: dict = field(default_factory=dict)
    shapes: list[str] = field(default_factory=list)  # the true scene's shape of each object id

    def summary(self) -> dict:
        n = len(self.attempts)
        succ = [a for a in self.attempts if (a["picked"] or 0) >= 1]
        planning = sum(a["planning_time"] for a in [*self.attempts, *self.skipped, *self.pushes])
        return {
            "objects": self.objects,
            "attempts": n,
            "unreachable": len(self.skipped),
            "success_rate": len(succ) / n if n else float("nan"),
            "picked_pct": 100.0 * self.in_bin / self.objects if self.objects else float("nan"),
            "objects_per_success": (sum(a["picked"] for a in succ) / len(succ)) if succ else float("nan"),
            "pph": 3600.0 * self.in_bin / self.cycle_time if self.cycle_time > 0 else float("nan"),
            "cycle_time_s": self.cycle_time,
            "robot_time_s": self.robot_time,
            "wait_perception_s": self.wait_perception,
            "wait_planning_s": self.wait_planning,
            "planning_time_s": planning,
            # the planning jobs' CPU time: their latency under `latency.mode` cpu
            "planning_cpu_s": sum(
                a.get("planning_cpu", 0.0) for a in [*self.attempts, *self.skipped, *self.pushes]
            ),
            "perception_time_s": self.perception_time,
            "retakes": self.retakes,
            # attempts that lost something on the way to the bin: in simulation, lifted objects
            # not in the bin; on hardware, the gripper's hold lost (OBJ 2 -> 3)
            "dropped": sum(dropped_in_transit(a) > 0 for a in self.attempts),
            "pushes": len(self.pushes),
            "push_time_s": self.push_time,
            "push_gain": self.push_gain(),
            "lone_grasps": sum(bool(a.get("lone")) for a in self.attempts),  # push-mog: see lone_reason
            "wall_time_s": self.wall_time,
            "finished": self.finished,
            "left_in_view": sum(w == "in view" for w, _ in self.left.values()),
            "left_out_of_view": sum(w == "out of view" for w, _ in self.left.values()),
            "left_off_table": sum(w == "off the table" for w, _ in self.left.values()),
        }

    def push_gain(self) -> int:
        """Objects the pushes gained: for each push, what the next grasp put in the bin beyond
        what the grasp that was possible without the push lifted in its physics check (0 for
        a push with no grasp after it)."""
        gain = 0
        for p in self.pushes:
            after = next((a for a in self.attempts if a["start"] >= p.get("end", math.inf)), None)
            if after is not None and after.get("picked") is not None:
                gain += after["picked"] - p["now"]
        return gain


SUMMARY_COLUMNS = [
    "objects",
    "attempts",
    "success_pct",
    "picked_pct",
    "objects_per_success",
    "pph",
    "cycle_time_s",
    "robot_time_s",
    "wait_perception_s",
    "wait_planning_s",
    "finished",
]


def attempt_line(k: int, a: dict) -> str:
    """One attempt of a run as a log line: what was grasped, by shape, and what came of it;
    or one push (push-mog): what was pushed, how far, and the grasp it set up."""
    if "push" in a:
        p = a["push"]
        shapes = a.get("shapes") or []
        return (
            f"push    {k:3d}  {p['distance'] * 1e3:.0f} mm, object {p['target']} to object {p['toward']}: "
            f"sets up a grasp of {len(a['group'])} ({' + '.join(shapes)}) that lifted {len(a['expected'])} "
            f"in physics (without the push: {a['now']})  [planning {a['planning_time']:.2f} s]"
        )
    what = "unrecognised blob(s)" if a.get("unrecognised") else " + ".join(a.get("shapes") or ()) or "?"
    line = f"attempt {k:3d}  grasp of {len(a['group'])}: {what}" + (
        " (after the push)" if a.get("after_push") else ""
    )
    if a.get("stopped"):
        line += f"  -> stopped on the way down ({a['stopped']['force']:.0f} N: a plate on an object)"
    if a.get("carried") is not None:
        line += f"  -> lifted {len(a['carried'])}"
    if a.get("picked") is not None:
        line += f", {a['picked']} in the bin ({a['in_bin']} in all)"
    if a.get("lost"):
        line += "  -> dropped in transit (the gripper lost its hold)"
    return line + f"  [planning {a['planning_time']:.2f} s, {a['physics_checks']} physics checks]"


def run_heading(sc: Scenario) -> str:
    """What a run is about to do: the table and mode, or the arm it drives."""
    hw = sc.hardware
    if not hw.enabled:
        return f"picking: {sc.scene}, mode {sc.planner.mode}"
    dry = f" -- DRY RUN, commands are logged to {hw.command_log or 'stderr'}, not sent" if hw.dry_run else ""
    return f"hardware: UR5 at {hw.robot_ip or '(no address)'}{dry}"


def run_text(run: PickRun, summary: dict | None = None) -> str:
    """A finished run as text: its summary table, what it left outside the bin and why, and
    the grasps it skipped."""
    from mog_drake.tables import format_table

    row = dict(summary or run.summary())
    row["success_pct"] = 100.0 * row["success_rate"]  # rates in percent, as `eval` prints them
    text = "\n" + format_table([row], SUMMARY_COLUMNS)
    for i, (where, p) in sorted(run.left.items()):
        shape = run.shapes[i] if run.shapes else "?"
        text += f"\nnot in the bin: object {i} ({shape}) {where} at {p}"
    for k in run.skipped:
        text += f"\nskipped at t={k['t']:.1f} s, unreachable: {k['reason']}"
    if run.finished == "gave_up":
        from mog_drake.planning.picking import MAX_MISSES

        text += (
            f"\ngave up: every object left was grasped {MAX_MISSES} times without being taken;"
            " it needs a person (or a look at why the grasps fail)"
        )
    return text
