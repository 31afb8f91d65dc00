"""The pick-and-place Diagram (run or drawn) and the gripper's bench check."""

from __future__ import annotations

import sys

from mog_drake.cli.common import emit, meshcat_of
from mog_drake.files import write_atomic
from mog_drake.planning.config import MODES


def add_parsers(sub) -> None:
    for name, helptext in (
        ("pick", "run the pick-and-place Diagram until the table is clear"),
        ("diagram", "draw the pick-and-place Diagram's wiring"),
    ):
        sp = sub.add_parser(name, help=helptext)
        sp.add_argument("--scenario", help="scenario YAML (default: the built-in one)")
        sp.add_argument("--seed", type=int, help="scene and planner seed")
        sp.add_argument("--mode", choices=MODES, help="multi-object (Alg. 1), single-object, or with pushes")
        sp.add_argument("--objects", type=int, help="objects on a generated cluttered table")
        sp.add_argument("--time-limit", type=float, help="simulated robot seconds")
        sp.add_argument("--json", action="store_true")
        if name == "pick":
            sp.add_argument("--robot-ip", help="hardware scenarios: the UR controller's address")
            sp.add_argument(
                "--dry-run", action="store_true", help="hardware: log every command instead of sending"
            )
            sp.add_argument("--meshcat", action="store_true", help="show it live in Meshcat")
            sp.add_argument("--record", metavar="HTML", help="write a self-contained Meshcat replay")
            sp.set_defaults(func=cmd_pick)
        else:
            sp.add_argument("-o", "--output", default="out/diagram.svg")
            sp.set_defaults(func=cmd_diagram)

    sp = sub.add_parser("gripper", help="bench check of a Robotiq 2F-85 (URCap socket)")
    sp.add_argument("action", choices=["open", "close", "status"])
    sp.add_argument("--ip", required=True)
    sp.add_argument("--port", type=int, default=63352)
    sp.add_argument("--force", type=float, default=40.0, help="N (20-235)")
    sp.add_argument("--timeout", type=float, default=2.0, help="s, hard deadline of each request")
    sp.add_argument("--move-timeout", type=float, default=5.0, help="s for the activation or a move to end")
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_gripper)


def _scenario(args):
    from mog_drake.scenario import load_scenario, with_overrides

    keys = ("seed", "mode", "objects", "time_limit", "robot_ip", "dry_run")
    return with_overrides(
        load_scenario(args.scenario), args.scenario, **{k: getattr(args, k, None) for k in keys}
    )


def cmd_pick(args) -> None:
    """Builds the pick-and-place Diagram and runs it until the table is clear."""
    from mog_drake.systems.pick import run_pick
    from mog_drake.systems.pick_run import attempt_line, run_heading, run_text

    sc = _scenario(args)
    meshcat = meshcat_of(args)
    if not args.json:
        print(run_heading(sc), flush=True)
    line = None if args.json else (lambda k, a: print(attempt_line(k, a), flush=True))
    run = run_pick(
        sc, meshcat=meshcat, on_attempt=line, realtime=sc.hardware.enabled and not sc.hardware.dry_run
    )
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

    out = write_diagram(MakePickDiagram(_scenario(args))[0], args.output)
    emit(args, {"output": str(out)}, f"wrote {out}")
