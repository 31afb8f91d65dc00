"""The pick-and-place Diagram (run or drawn) and the gripper's bench check."""

from __future__ import annotations

import sys

from mog_drake.cli.common import emit, meshcat_of
from mog_drake.files import write_atomic
from mog_drake.planning.config import MODES

SCENARIO_HELP = (
    "scenario YAML, or the name of one shipped in models/ (realistic, hardware, ...); "
    "default: the built-in one (models/scenario.yaml lists every setting)"
)


def add_parsers(sub) -> None:
    sp = sub.add_parser("pick", help="run the pick-and-place Diagram until the table is clear")
    sp.add_argument("--scenario", help=SCENARIO_HELP)
    sp.add_argument(
        "--seed",
        type=int,
        help="the table's and the planner's seed, a whole number (default: the scenario's, 0)",
    )
    sp.add_argument(
        "--mode",
        choices=MODES,
        help="mog: multi-object grasps (the paper's Alg. 1); sog: one object at a time; "
        "push-mog: with consolidating pushes (default: the scenario's, mog)",
    )
    sp.add_argument(
        "--objects",
        type=int,
        help="objects on the seeded cluttered table, 1-33 (default: the scenario's, all 33)",
    )
    sp.add_argument(
        "--time-limit",
        type=float,
        help="s of simulated robot time before the run stops (default: the scenario's, 600)",
    )
    sp.add_argument("--json", action="store_true", help="print one JSON document instead of text")
    sp.add_argument(
        "--robot-ip", help="hardware scenarios: the UR controller's IP address (default: the scenario's)"
    )
    sp.add_argument(
        "--dry-run",
        action="store_true",
        help="hardware scenarios: log every command to a file instead of sending it",
    )
    sp.add_argument(
        "--meshcat", action="store_true", help="show the run live in Meshcat (its address on stderr)"
    )
    sp.add_argument(
        "--record",
        metavar="HTML",
        help="write the run as a self-contained Meshcat replay, .html (default: none)",
    )
    sp.set_defaults(func=cmd_pick)

    sp = sub.add_parser("diagram", help="draw the pick-and-place Diagram's systems and their wiring")
    sp.add_argument("--scenario", help=SCENARIO_HELP + "; its station (simulated or hardware) is drawn")
    sp.add_argument(
        "-o",
        "--output",
        default="out/diagram.svg",
        help="file to write: .svg, .png, .pdf or .dot (default: out/diagram.svg)",
    )
    sp.add_argument("--json", action="store_true", help="print one JSON document instead of text")
    sp.set_defaults(func=cmd_diagram)

    sp = sub.add_parser("gripper", help="bench check of a Robotiq 2F-85 over the UR's URCap socket")
    sp.add_argument("action", choices=["open", "close", "status"], help="what to do")
    sp.add_argument(
        "--ip", required=True, help="the UR controller's IP address (the URCap serves the gripper)"
    )
    sp.add_argument("--port", type=int, default=63352, help="the URCap socket's TCP port (default: 63352)")
    sp.add_argument("--force", type=float, default=40.0, help="grip force in N, 20-235 (default: 40)")
    sp.add_argument("--timeout", type=float, default=2.0, help="s, the deadline of each request (default: 2)")
    sp.add_argument(
        "--move-timeout", type=float, default=5.0, help="s for the activation or a move to end (default: 5)"
    )
    sp.add_argument("--json", action="store_true", help="print one JSON document instead of text")
    sp.set_defaults(func=cmd_gripper)


def _scenario(args):
    from mog_drake.scenario import load_scenario, with_overrides

    keys = ("seed", "mode", "objects", "time_limit", "robot_ip", "dry_run")
    return with_overrides(
        load_scenario(args.scenario), args.scenario, **{k: getattr(args, k, None) for k in keys}
    )


def cmd_pick(args) -> None:
    """Builds the pick-and-place Diagram and runs it until the table is clear."""
    from mog_drake.errors import StationFault
    from mog_drake.systems.pick import run_pick
    from mog_drake.systems.pick_run import attempt_line, run_heading, run_text

    sc = _scenario(args)
    meshcat = meshcat_of(args)
    if not args.json:
        print(run_heading(sc), flush=True)
    line = None if args.json else (lambda k, a: print(attempt_line(k, a), flush=True))
    try:
        run = run_pick(
            sc, meshcat=meshcat, on_attempt=line, realtime=sc.hardware.enabled and not sc.hardware.dry_run
        )
    except StationFault as e:  # what was done, then the fault's one line (exit 3)
        if e.run is not None:
            doc = {
                "summary": e.run.summary(),
                "attempts": e.run.attempts,
                "fault": str(e),
                "state": str(e.path),
            }
            emit(args, doc, run_text(e.run, e.run.summary()))
        raise
    summary = run.summary()
    if args.record:
        write_atomic(args.record, meshcat.StaticHtml())
        summary["replay"] = args.record
    doc = {"summary": summary, "attempts": run.attempts, "skipped": run.skipped, "pushes": run.pushes}
    emit(args, doc, run_text(run, summary) + (f"\nreplay: {args.record}" if args.record else ""))
    if args.meshcat and sys.stdin.isatty():
        input("Meshcat is serving the replay; press Enter to quit. ")


def cmd_gripper(args) -> None:
    """Bench check of a Robotiq 2F-85 over the URCap socket (`robotiq.bench_check`)."""
    from mog_drake.hardware.robotiq import bench_check

    emit(args, *bench_check(args.ip, args.port, args.action, args.force, args.timeout, args.move_timeout))


def cmd_diagram(args) -> None:
    """Draws the pick-and-place Diagram's wiring: graphviz if installed, else matplotlib; .dot writes the source."""
    from mog_drake.plotting import write_diagram
    from mog_drake.systems.pick import MakePickDiagram

    out = write_diagram(MakePickDiagram(_scenario(args)).diagram, args.output)
    emit(args, {"output": str(out)}, f"wrote {out}")
