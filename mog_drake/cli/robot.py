"""The pick-and-place Diagram (run or drawn) and the gripper's bench check."""

from __future__ import annotations

import sys
from pathlib import Path

from mog_drake.cli.common import emit, meshcat_of
from mog_drake.errors import MogError
from mog_drake.outputs import write_atomic
from mog_drake.planning.config import MODES


def add_parsers(sub) -> None:
    for name, helptext in (
        ("pick", "run the pick-and-place Diagram until the table is clear"),
        ("diagram", "draw the pick-and-place Diagram's wiring"),
    ):
        sp = sub.add_parser(name, help=helptext)
        sp.add_argument("--scenario", help="scenario YAML (default: the built-in one)")
        sp.add_argument("--seed", type=int, help="scene and planner seed")
        sp.add_argument(
            "--mode",
            choices=MODES,
            help="multi-object (Alg. 1), single-object, or multi-object with consolidating pushes (push-mog)",
        )
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
    from dataclasses import replace

    from mog_drake.scenario import load_scenario

    sc = load_scenario(args.scenario)
    if args.seed is not None:
        if hasattr(sc.scene, "seed"):
            sc.scene = replace(sc.scene, seed=args.seed)
        sc.planner = replace(sc.planner, seed=args.seed)
    if getattr(args, "mode", None):
        sc.planner = replace(sc.planner, mode=args.mode)
    if getattr(args, "objects", None):
        if not hasattr(sc.scene, "n_objects"):
            raise MogError("--objects applies to a cluttered table (scene: !ClutteredScene)")
        sc.scene = replace(sc.scene, n_objects=args.objects)
    if getattr(args, "time_limit", None):
        sc.time_limit = args.time_limit
    for flag, given in (
        ("--robot-ip", getattr(args, "robot_ip", None)),
        ("--dry-run", getattr(args, "dry_run", False)),
    ):
        if given and not sc.hardware.enabled:
            raise MogError(
                f"{flag} applies to a hardware scenario (hardware.enabled: true, e.g. models/hardware.yaml);"
                f" {args.scenario or 'the default scenario'} is simulated"
            )
    if getattr(args, "robot_ip", None):
        sc.hardware = replace(sc.hardware, robot_ip=args.robot_ip)
    if getattr(args, "dry_run", False):
        sc.hardware = replace(sc.hardware, dry_run=True)
    return sc


def cmd_pick(args) -> int:
    """Builds the pick-and-place Diagram and runs it until the table is clear."""
    from mog_drake.systems.pick import attempt_line, run_pick, run_text

    sc = _scenario(args)
    meshcat = meshcat_of(args)
    if meshcat is not None:
        from mog_drake.station.sim import frame_work_cell

        frame_work_cell(meshcat, sc)

    def line(k, a):
        if not args.json:
            print(attempt_line(k, a), flush=True)

    hw = sc.hardware.enabled
    if not args.json and not hw:
        print(f"picking: {sc.scene}, mode {sc.planner.mode}", flush=True)
    if hw and not args.json:
        print(
            f"hardware: UR5 at {sc.hardware.robot_ip or '(no address)'}"
            + (
                f" -- DRY RUN, commands are logged to {sc.hardware.command_log or 'stderr'}, not sent"
                if sc.hardware.dry_run
                else ""
            ),
            flush=True,
        )
    run = run_pick(sc, meshcat=meshcat, on_attempt=line, realtime=hw and not sc.hardware.dry_run)
    summary = run.summary()
    if args.record:
        write_atomic(args.record, meshcat.StaticHtml())
        summary["replay"] = args.record
    emit(
        args,
        {"summary": summary, "attempts": run.attempts, "skipped": run.skipped, "pushes": run.pushes},
        run_text(run, summary) + (f"\nreplay: {args.record}" if args.record else ""),
    )
    if args.meshcat and sys.stdin.isatty():
        input("Meshcat is serving the replay; press Enter to quit. ")
    return 0


def cmd_gripper(args) -> int:
    """Bench check of a Robotiq 2F-85 over the URCap socket (`robotiq.bench_check`): a fault,
    an ignored command, a move that does not end or a peer that talks nonsense ends in one
    line and exit 3."""
    from mog_drake.hardware.robotiq import bench_check

    status = bench_check(args.ip, args.port, args.action, args.force, args.timeout, args.move_timeout)
    emit(
        args,
        status,
        f"gripper at {args.ip}:{args.port}: {args.action}: {status['object_text']}; "
        f"width {status['width'] * 1e3:.1f} mm (POS {status['pos']}, OBJ {status['object']}, no fault)",
    )
    return 0


def cmd_diagram(args) -> int:
    """Draws the pick-and-place Diagram's wiring: graphviz if installed, else matplotlib; .dot writes the source."""
    import shutil
    import subprocess

    from mog_drake.systems.pick import MakePickDiagram

    sc = _scenario(args)
    diagram, _ = MakePickDiagram(sc)
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix == ".dot":
        out.write_text(diagram.GetGraphvizString(max_depth=1))
    elif shutil.which("dot"):
        subprocess.run(
            ["dot", f"-T{out.suffix[1:] or 'svg'}", "-o", str(out)],
            input=diagram.GetGraphvizString(max_depth=1).encode(),
            check=True,
        )
    else:  # no graphviz: draw the top-level wiring with matplotlib
        from mog_drake import plotting

        plotting.save(plotting.diagram_figure(diagram), out)
    emit(args, {"output": str(out)}, f"wrote {out}")
    return 0
