"""The `mog-drake` command line. Thin: parse, call, print.

A user error prints one line `mog-drake: error: ...` and exits 2, with no traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import re
import sys
from pathlib import Path

import numpy as np

from mog_drake.errors import MogError, Terminated, stop_on_signals
from mog_drake.experiments.bench import BENCHES
from mog_drake.outputs import check_writable, write_atomic
from mog_drake.planning.config import MODES
from mog_drake.tables import format_table


# --- helpers ------------------------------------------------------------------------------
def _library(args):
    from mog_drake.scenes import ShapeLibrary, default_library

    files = getattr(args, "shapes", None) or []
    return ShapeLibrary.load(*files) if files else default_library()


def _load_scene(args):
    from mog_drake.scenes import Scene

    lib = _library(args) if getattr(args, "shapes", None) else None
    return Scene.load(args.scene, lib)


def resolve_group(scene, group_arg, gripper=None) -> tuple[tuple[int, ...], str]:
    """The group to grasp: --group if given, else the scene's own, else Alg. 1's first group."""
    from mog_drake.geometry import GripperGeometry

    if group_arg:
        for g in group_arg:
            if not 0 <= g < len(scene):
                raise MogError(
                    f"--group names object {g}, but the scene has {len(scene)} objects (0..{len(scene) - 1})"
                )
        if len(set(group_arg)) != len(group_arg):
            raise MogError("--group names an object twice")
        return tuple(group_arg), "argument"
    return scene.default_group((gripper or GripperGeometry()).w_g)


def plain(obj):
    """``obj`` as strict JSON values: NaN and infinities become null (JSON has no NaN),
    numpy scalars and arrays Python numbers and lists."""
    if isinstance(obj, dict):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return plain(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _emit(args, doc: dict, text: str) -> None:
    if getattr(args, "json", False):
        print(json.dumps(plain(doc), indent=2, allow_nan=False))
    else:
        print(text)


def _grasp_arg(values) -> np.ndarray:
    g = np.array(values, dtype=float)
    if not np.all(np.isfinite(g)):
        raise MogError(f"--grasp must be three finite numbers X Y THETA, got {values}")
    return g


# --- commands -----------------------------------------------------------------------------
def cmd_shapes(args) -> int:
    lib = _library(args)
    recs = [lib[n].to_record() for n in lib.shapes]
    rows = [
        {
            "name": r["name"],
            "sides": r["sides"],
            "height_mm": r["height"] * 1e3,
            "mass_g": r["mass"] * 1e3,
            "d_fmin_mm": r["d_fmin"] * 1e3,
            "final_diameters_mm": ", ".join(f"{d * 1e3:.2f}" for d in r["final_diameters"]),
        }
        for r in recs
    ]
    _emit(args, {"shapes": recs, "inventories": lib.inventories}, format_table(rows))
    return 0


def cmd_scene_generate(args) -> int:
    from mog_drake.scenes import ClutterParams, cluttered_scene, row_scene

    rng = np.random.default_rng(args.seed)
    lib = _library(args)
    if args.kind == "row":
        if args.row_class is None:
            raise MogError("--kind row needs --class N (1..7)")
        scene = row_scene(args.row_class, rng, lib)
    else:
        scene = cluttered_scene(
            rng,
            lib,
            inventory=args.inventory,
            n_objects=args.objects,
            params=ClutterParams(n_clusters=args.clusters),
        )
    scene.meta["seed"] = args.seed
    if args.shapes:
        scene.shapes_file = str(Path(args.shapes[-1]).resolve())
    if args.output:
        scene.save(args.output)
    doc = {"output": args.output, "objects": len(scene), "meta": scene.meta, "scene": scene.to_dict()}
    if args.output:
        _emit(args, doc, f"wrote {args.output}: {len(scene)} objects ({args.kind}, seed {args.seed})")
    else:
        import yaml

        _emit(args, doc, yaml.safe_dump(scene.to_dict(), sort_keys=False, default_flow_style=None))
    return 0


def cmd_scene_show(args) -> int:
    from mog_drake import plotting
    from mog_drake.geometry import GripperGeometry, candidate_grasps, evaluate_grasps, rank_grasp_cands

    scene = _load_scene(args)
    gripper = GripperGeometry()
    group, _ = resolve_group(scene, args.group, gripper)
    ev = order = None
    if args.candidates:
        polys = scene.polygons()
        ev = evaluate_grasps(
            polys, group, candidate_grasps(polys, group, args.positions, args.orientations), gripper
        )
        order = rank_grasp_cands(ev)
    grasp = _grasp_arg(args.grasp) if args.grasp else None
    fig = plotting.scene_figure(
        scene,
        group,
        ev,
        order,
        top=args.top,
        gripper=gripper,
        grasp=grasp,
        title=f"{args.scene}  group {list(group)}",
    )
    plotting.save(fig, args.output)
    _emit(args, {"output": args.output, "group": list(group)}, f"wrote {args.output}")
    return 0


def cmd_check(args) -> int:
    from mog_drake.geometry import GripperGeometry, evaluate_grasps
    from mog_drake.geometry.conditions import record_lines

    scene = _load_scene(args)
    gripper = GripperGeometry()
    group, source = resolve_group(scene, args.group, gripper)
    grasp = _grasp_arg(args.grasp)
    rec = evaluate_grasps(scene.polygons(), group, grasp[None, :], gripper).record(0)
    doc = {"scene": args.scene, "group": list(group), "group_source": source, **rec}
    lines = record_lines(rec)
    lines.insert(1, f"group      {list(group)} ({source})")
    if args.simulate or args.meshcat or args.record:
        res = _simulate(scene, group, grasp, args)
        doc["simulation"] = res.to_dict()
        lines.append(res.text())
        if args.record:
            lines.append(f"replay     {args.record}")
    _emit(args, doc, "\n".join(lines))
    if args.meshcat and sys.stdin.isatty():
        input("Meshcat is serving the replay; press Enter to quit. ")
    return 0


def _simulate(scene, group, grasp, args):
    """Runs the physics verifier on one grasp, optionally shown in Meshcat and recorded."""
    from dataclasses import replace

    from mog_drake.scenario import load_scenario
    from mog_drake.sim.verifier import DrakeVerifier

    sc = load_scenario(args.scenario)  # a bad file is refused before anything starts
    physics = sc.gripper
    if args.force is not None:
        if not (0 < args.force <= 235):
            raise MogError(f"--force must be in (0, 235] N (the 2F-85's range), got {args.force}")
        physics = replace(physics, force_limit=args.force)
    meshcat = _meshcat(args)
    res = DrakeVerifier(sc.verifier, physics=physics, meshcat=meshcat).check(scene, group, grasp)
    if args.record:
        write_atomic(args.record, meshcat.StaticHtml())
    return res


def cmd_candidates(args) -> int:
    from mog_drake.geometry import GripperGeometry, candidate_grasps, evaluate_grasps, rank_grasp_cands
    from mog_drake.geometry.conditions import candidate_rows

    scene = _load_scene(args)
    gripper = GripperGeometry()
    group, source = resolve_group(scene, args.group, gripper)
    polys = scene.polygons()
    ev = evaluate_grasps(
        polys, group, candidate_grasps(polys, group, args.positions, args.orientations), gripper
    )
    order = rank_grasp_cands(ev)
    recs = []
    for rank, i in enumerate(order):
        r = ev.record(int(i))
        r["rank"] = rank
        recs.append(r)
    counts = {
        v: sum(1 for r in recs if r["verdict"] == v) for v in ("collision", "diameter", "area", "passed")
    }
    doc = {
        "scene": args.scene,
        "group": list(group),
        "group_source": source,
        "h_fmin": ev.h_fmin,
        "counts": counts,
        "candidates": recs,
    }
    shown = [r for r in recs if r["verdict"] != "collision" or args.all][: args.limit]
    rows = candidate_rows(shown)
    text = (
        f"group {list(group)} ({source}); h_fmin = {ev.h_fmin * 1e3:.2f} mm; {len(recs)} candidates: "
        + ", ".join(f"{k} {v}" for k, v in counts.items())
        + "\n"
        + format_table(rows)
    )
    _emit(args, doc, text)
    return 0


def cmd_plan(args) -> int:
    from mog_drake.planning.planner import GraspPlanner, PlannerConfig
    from mog_drake.sim.verifier import DrakeVerifier

    scene = _load_scene(args)
    group, source = resolve_group(scene, args.group)
    planner = GraspPlanner(DrakeVerifier(), PlannerConfig(method=args.method, max_physics=args.max_physics))
    res = planner.plan(scene, group, rng=np.random.default_rng(args.seed))
    doc = {"scene": args.scene, "group_source": source, **res.to_dict()}
    _emit(args, doc, res.text().replace(f"group {list(res.group)}", f"group {list(res.group)} ({source})", 1))
    return 0


def _parse_classes(text: str) -> list[int]:
    try:
        if "-" in text:
            a, b = (int(v) for v in text.split("-"))
            classes = list(range(a, b + 1))
        else:
            classes = [int(v) for v in text.split(",")]
    except ValueError:
        raise MogError(f"--classes must look like 2-7 or 2,3,5, got {text!r}") from None
    from mog_drake.scenes import ROW_CLASSES

    bad = [c for c in classes if c not in ROW_CLASSES]
    if bad or not classes:
        raise MogError(f"--classes: {bad or text} not among the row classes {sorted(ROW_CLASSES)}")
    return classes


def cmd_eval(args) -> int:
    if getattr(args, "summary_only", False):
        from mog_drake.experiments.sweep import summary_only

        with summary_only():
            return _cmd_eval(args)
    return _cmd_eval(args)


def _cmd_eval(args) -> int:
    import os

    out = Path(args.out)
    jobs = args.jobs or os.cpu_count() or 1
    progress = not args.json
    if args.experiment == "picking":
        from mog_drake.experiments import picking_eval

        modes = [m.strip() for m in args.modes.split(",") if m.strip()]
        if not modes or any(m not in MODES for m in modes):
            raise MogError(f"--modes must list some of {', '.join(MODES)}, got {args.modes!r}")
        scenario = ""
        if args.scenario:
            from mog_drake.scenario import load_scenario

            load_scenario(args.scenario)  # refuses a bad file before anything runs
            scenario = Path(args.scenario).read_text()
        summary, results = picking_eval.run(
            args.scenes,
            modes,
            args.seed,
            out,
            args.objects,
            args.time_limit,
            jobs,
            args.ray,
            progress,
            scenario,
            args.compare,
        )
        text = picking_eval.report(summary, results, out, args.compare)
    elif args.experiment == "conditions":
        from mog_drake.experiments import conditions

        summary, _ = conditions.run(
            _parse_classes(args.classes),
            args.scenes_per_class,
            args.seed,
            out,
            jobs,
            args.ray,
            progress,
            args.positions,
            args.orientations,
        )
        text = conditions.report(summary, out)
    else:
        from mog_drake.experiments import planning_eval
        from mog_drake.planning.planner import METHODS

        methods = [m.strip() for m in args.methods.split(",") if m.strip()]
        bad = [m for m in methods if m not in METHODS]
        if bad or not methods:
            raise MogError(f"--methods: unknown {bad or args.methods} (known: {', '.join(METHODS)})")
        summary, _ = planning_eval.run(
            _parse_classes(args.classes),
            args.scenes_per_class,
            args.seed,
            out,
            methods,
            jobs,
            args.ray,
            args.max_physics,
            progress,
            args.positions,
            args.orientations,
        )
        text = planning_eval.report(summary, out)
    _emit(args, summary, text)
    return 0


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


def _meshcat(args):
    """A Meshcat for --meshcat (its address on stderr, once) or --record, else None. Drake's
    own INFO line about it is kept off stderr."""
    if not (args.meshcat or args.record):
        return None
    import logging

    from pydrake.geometry import StartMeshcat

    drake_log = logging.getLogger("drake")
    level = drake_log.level
    drake_log.setLevel(logging.WARNING)
    try:
        meshcat = StartMeshcat()
    finally:
        drake_log.setLevel(level)
    if args.meshcat:
        print(f"meshcat: {meshcat.web_url()}", file=sys.stderr)
    return meshcat


def cmd_pick(args) -> int:
    """Builds the pick-and-place Diagram and runs it until the table is clear."""
    from mog_drake.systems.pick import attempt_line, run_pick, run_text

    sc = _scenario(args)
    meshcat = _meshcat(args)
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
    _emit(
        args,
        {"summary": summary, "attempts": run.attempts, "skipped": run.skipped, "pushes": run.pushes},
        run_text(run, summary) + (f"\nreplay: {args.record}" if args.record else ""),
    )
    if args.meshcat and sys.stdin.isatty():
        input("Meshcat is serving the replay; press Enter to quit. ")
    return 0


def cmd_gripper(args) -> int:
    """Bench check of a Robotiq 2F-85 over the URCap socket. A move waits for its end and says
    whether it stopped on an object; a fault, an ignored command, a move that does not end or
    a peer that talks nonsense ends in one line and exit 3."""
    from mog_drake.hardware.robotiq import RobotiqCalibration, RobotiqClient

    cal = RobotiqCalibration()
    # Every argument is checked before anything is sent.
    try:
        cal.force_to_byte(args.force)
    except MogError as e:
        raise MogError(f"--force: {e}") from None
    for name in ("timeout", "move_timeout"):
        v = getattr(args, name)
        if not (math.isfinite(v) and v > 0):
            raise MogError(f"--{name.replace('_', '-')} must be a positive number of seconds, got {v}")
    with RobotiqClient(
        args.ip,
        args.port,
        timeout=args.timeout,
        calibration=cal,
        activation_timeout=args.move_timeout,
        move_timeout=args.move_timeout,
    ) as g:
        if args.action in ("open", "close"):
            g.activate()
            status = g.move(cal.stroke if args.action == "open" else 0.0, force=args.force)
        else:
            status = g.status()
            g.check_fault("in the status read")
    _emit(
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
    _emit(args, {"output": str(out)}, f"wrote {out}")
    return 0


def cmd_bench(args) -> int:
    from mog_drake.experiments import bench

    doc, text = bench.run(
        args.what,
        args.scenes,
        args.seed,
        args.toppled,
        progress=not args.json,
        budget=args.budget or 0.0,
        tables=args.tables,
        out=args.out or "out/bench_verifier",
    )
    _emit(args, doc, text)
    return 0


def cmd_demo(args) -> int:
    """The planner's geometry on two example scenes: a table and a picture each."""
    from mog_drake.experiments.geometry_demo import geometry_demo

    doc, text = geometry_demo(args.out, args.seed)
    _emit(args, doc, text.strip())
    return 0


# --- parser -------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="mog-drake", description="Multi-object push-grasping in the plane, on Drake.")
    sub = p.add_subparsers(dest="command", required=True)

    def common(sp, scene=True):
        sp.add_argument("--json", action="store_true", help="print one JSON document")
        sp.add_argument(
            "--shapes", action="append", metavar="FILE", help="extra shape library YAML (repeatable)"
        )
        if scene:
            sp.add_argument("scene", help="scene YAML file")

    sp = sub.add_parser("shapes", help="list the object library")
    common(sp, scene=False)
    sp.set_defaults(func=cmd_shapes)

    sc = sub.add_parser("scene", help="generate or draw scenes").add_subparsers(
        dest="scene_command", required=True
    )
    sp = sc.add_parser("generate", help="generate a seeded scene")
    common(sp, scene=False)
    sp.add_argument("--kind", choices=["row", "cluttered"], default="row")
    sp.add_argument(
        "--class",
        dest="row_class",
        type=int,
        help="row class: number of objects, 1..7 (the paper's are 2..7)",
    )
    sp.add_argument("--objects", type=int, help="cluttered: number of objects (default: whole inventory)")
    sp.add_argument("--inventory", default="isrr33")
    sp.add_argument("--clusters", type=int, default=4)
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument("-o", "--output", help="scene YAML to write (default: print it)")
    sp.set_defaults(func=cmd_scene_generate)

    sp = sc.add_parser("show", help="draw a scene to a PNG")
    common(sp)
    sp.add_argument("-o", "--output", required=True, help="PNG to write")
    sp.add_argument("--group", type=int, nargs="+")
    sp.add_argument("--candidates", action="store_true", help="overlay candidates coloured by verdict")
    sp.add_argument("--grasp", type=float, nargs=3, metavar=("X", "Y", "THETA"), help="draw this grasp")
    sp.add_argument("--top", type=int, default=3, help="S regions of the top N passing candidates")
    sp.add_argument("--positions", type=int, default=70)
    sp.add_argument("--orientations", type=int, default=7)
    sp.set_defaults(func=cmd_scene_show)

    sp = sub.add_parser("check", help="the two necessary conditions for one grasp")
    common(sp)
    sp.add_argument("--grasp", type=float, nargs=3, metavar=("X", "Y", "THETA"), required=True)
    sp.add_argument("--group", type=int, nargs="+")
    sp.add_argument(
        "--simulate", action="store_true", help="also run the physics verifier (close, lift, hold)"
    )
    sp.add_argument(
        "--meshcat", action="store_true", help="show the simulation live in Meshcat (implies --simulate)"
    )
    sp.add_argument(
        "--record", metavar="HTML", help="write a self-contained Meshcat replay (implies --simulate)"
    )
    sp.add_argument("--force", type=float, help="grip force limit per jaw in N (default 40)")
    sp.add_argument(
        "--scenario", help="scenario YAML whose verifier and gripper the simulation uses (default: built-in)"
    )
    sp.set_defaults(func=cmd_check)

    sp = sub.add_parser("candidates", help="every grasp candidate with its figures, ranked by A_T")
    common(sp)
    sp.add_argument("--group", type=int, nargs="+")
    sp.add_argument("--positions", type=int, default=70, help="Np")
    sp.add_argument("--orientations", type=int, default=7, help="Ntheta")
    sp.add_argument("--limit", type=int, default=20, help="rows in the text table")
    sp.add_argument("--all", action="store_true", help="include colliding candidates in the text table")
    sp.set_defaults(func=cmd_candidates)

    sp = sub.add_parser("plan", help="plan a grasp for a group (GraspPlanner, Alg. 2)")
    common(sp)
    sp.add_argument("--group", type=int, nargs="+")
    sp.add_argument("--method", default="gp", help="gp, rand-phys, rank-phys, rand-fil-phys or single")
    sp.add_argument("--seed", type=int, default=0, help="for the randomised methods")
    sp.add_argument("--max-physics", type=int, help="stop after this many physics checks")
    sp.set_defaults(func=cmd_plan)

    ev = sub.add_parser("eval", help="the paper's experiments").add_subparsers(
        dest="experiment", required=True
    )
    for name, helptext in (
        ("conditions", "necessary conditions vs physics (Sec. 7.2)"),
        ("planner", "GP vs its baselines (Sec. 7.3)"),
    ):
        sp = ev.add_parser(name, help=helptext)
        sp.add_argument("--classes", default="2-7", help="row classes, e.g. 2-7 or 2,4")
        sp.add_argument("--scenes-per-class", type=int, default=50)
        sp.add_argument("--seed", type=int, default=0)
        sp.add_argument("--out", required=True, help="output folder (resumes what it holds)")
        sp.add_argument("--jobs", type=int, help="parallel processes (default: all cores)")
        sp.add_argument("--ray", metavar="ADDRESS", help="run on an existing Ray cluster")
        sp.add_argument("--positions", type=int, default=70, help="Np")
        sp.add_argument("--orientations", type=int, default=7, help="Ntheta")
        sp.add_argument("--json", action="store_true")
        if name == "planner":
            sp.add_argument("--methods", default="gp,rand-phys,rank-phys,rand-fil-phys")
            sp.add_argument(
                "--max-physics", type=int, help="cap physics checks per plan (speed-ups become lower bounds)"
            )
        sp.add_argument("--summary-only", action="store_true", help="summarise what is done; run nothing")
        sp.set_defaults(func=cmd_eval)
    sp = ev.add_parser("picking", help="multi- vs single-object picking on cluttered tables (Table 1)")
    sp.add_argument("--scenes", type=int, default=20)
    sp.add_argument("--modes", default="mog,sog")
    sp.add_argument("--objects", type=int, default=33, help="objects per table (the isrr33 inventory)")
    sp.add_argument("--time-limit", type=float, default=900.0, help="simulated robot seconds per table")
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument(
        "--scenario",
        help="scenario YAML whose settings every run uses (its scene, time limit, mode and seed are set by the sweep)",
    )
    sp.add_argument("--out", required=True)
    sp.add_argument("--jobs", type=int)
    sp.add_argument("--ray", metavar="ADDRESS")
    sp.add_argument("--json", action="store_true")
    sp.add_argument("--summary-only", action="store_true", help="summarise what is done; run nothing")
    sp.add_argument(
        "--compare",
        metavar="DIR",
        help="another picking sweep's --out folder (A): paired differences of this one (B) on the tables both ran",
    )
    sp.set_defaults(func=cmd_eval)

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

    sp = sub.add_parser("bench", help="benchmarks that print a table")
    sp.add_argument(
        "what",
        choices=BENCHES,
    )
    sp.add_argument(
        "--scenes",
        type=int,
        default=20,
        help="scenes per class (geometry, verifier); tables (perception, replanning); copies per shape (rest)",
    )
    sp.add_argument(
        "--tables", type=int, default=3, help="verifier: 33-object tables whose checks are replayed"
    )
    sp.add_argument("--out", help="verifier: folder for the scenes of the disagreements, to replay")
    sp.add_argument("--toppled", type=int, default=0, help="perception: bars laid on their side per table")
    sp.add_argument(
        "--budget",
        type=float,
        default=None,
        help="replanning: compare the defaults with planner.decision_budget_s = this (s)",
    )
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_bench)

    sp = sub.add_parser("demo", help="the planner's geometry on example scenes (table + picture)")
    sp.add_argument("--out", default="out/demo")
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_demo)
    return p


class _UsageError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    """argparse, with its errors on one line (`mog-drake: error: ...`, exit 2) and numbers in
    exponent form (-1e-3) read as numbers, not options. Subparsers are of this class too."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message):
        raise _UsageError(" ".join(str(message).split()))


IMAGE_SUFFIXES = (".png", ".svg", ".pdf", ".jpg", ".jpeg")


# Candidate grids past these sizes take minutes and gigabytes and see nothing more.
MOST = {"positions": 10_000, "orientations": 360}


def check_args(args) -> None:
    """Refuses bad numbers and output paths before anything runs."""
    for name in (
        "positions",
        "orientations",
        "limit",
        "scenes",
        "objects",
        "clusters",
        "top",
        "candidates",
        "scenes_per_class",
        "jobs",
        "max_physics",
    ):
        v = getattr(args, name, None)
        if v is not None and not isinstance(v, bool) and v < 1:
            raise MogError(f"--{name.replace('_', '-')} must be at least 1, got {v}")
    for name, most in MOST.items():
        v = getattr(args, name, None)
        if v is not None and v > most:
            raise MogError(f"--{name} must be at most {most:,} (the grid's memory and time), got {v:,}")
    if args.command == "gripper":
        if not args.ip.strip():
            raise MogError("--ip must name the gripper's host (the UR controller's address)")
        if not 1 <= args.port <= 65535:
            raise MogError(f"--port must be a TCP port (1-65535), got {args.port}")
    tables = getattr(args, "tables", None)
    if tables is not None and tables < 0:
        raise MogError(f"--tables must be at least 0, got {tables}")
    seed = getattr(args, "seed", None)
    if seed is not None and not 0 <= seed < 2**63:
        raise MogError(f"--seed must be a whole number >= 0, got {seed}")
    for name in ("time_limit", "timeout", "move_timeout", "window", "force", "budget"):
        v = getattr(args, name, None)
        if v is not None and not (math.isfinite(v) and v > 0):
            raise MogError(f"--{name.replace('_', '-')} must be a positive number, got {v}")
    for name, suffixes in (("output", IMAGE_SUFFIXES), ("record", (".html",))):
        v = getattr(args, name, None)
        if not v:
            continue
        path = Path(v)
        if path.is_dir():
            raise MogError(f"--{name} {v} is a directory: give a file name")
        if name == "output" and args.command == "scene" and args.scene_command == "generate":
            continue  # a scene YAML, any name
        if name == "output" and args.command == "diagram":
            suffixes = (*suffixes, ".dot")
        if path.suffix.lower() not in suffixes:
            raise MogError(
                f"--{name} {v}: unknown file type {path.suffix or '(none)'} (use {', '.join(suffixes)})"
            )
        check_writable(path, f"--{name}")
    out = getattr(args, "out", None)
    if out and Path(out).exists() and not Path(out).is_dir():
        raise MogError(f"--out {out} is a file: give a folder")


@contextlib.contextmanager
def _one_line_warnings():
    """Within the block a warning is one line on stderr, ``mog-drake: warning: ...``, and
    numpy's RuntimeWarnings (a mean of nothing, 0 / 0) are not shown: their NaN is in the
    table already."""
    import warnings

    def show(message, category, filename, lineno, file=None, line=None):
        print(f"mog-drake: warning: {' '.join(str(message).split())}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        warnings.showwarning = show
        yield


def main(argv: list[str] | None = None) -> int:
    try:
        with stop_on_signals(), _one_line_warnings():
            args = build_parser().parse_args(argv)
            check_args(args)
            return int(args.func(args) or 0)
    except _UsageError as e:
        print(f"mog-drake: error: {e}", file=sys.stderr)
        return 2
    except MogError as e:  # HardwareFault included: exit 3
        print(f"mog-drake: error: {' '.join(str(e).split())}", file=sys.stderr)
        return e.exit_code
    except OSError as e:  # a path that cannot be written or read (permissions, a full disk)
        where = f": {e.filename}" if getattr(e, "filename", None) else ""
        print(f"mog-drake: error: {e.strerror or e}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("mog-drake: interrupted", file=sys.stderr)
        return 130
    except Terminated as e:
        print(f"mog-drake: terminated by {e}", file=sys.stderr)
        return e.exit_code


if __name__ == "__main__":
    sys.exit(main())
