"""Commands on one scene at a time: the shape library, scenes, the necessary conditions for a
grasp, candidates, GraspPlanner, and the geometry demo."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from mog_drake.cli.common import add_common, emit, grasp_arg, library, load_scene, meshcat_of, resolve_group
from mog_drake.errors import MogError
from mog_drake.outputs import write_atomic
from mog_drake.tables import format_table


def add_parsers(sub) -> None:
    sp = sub.add_parser("shapes", help="list the object library")
    add_common(sp, scene=False)
    sp.set_defaults(func=cmd_shapes)

    sc = sub.add_parser("scene", help="generate or draw scenes").add_subparsers(
        dest="scene_command", required=True
    )
    sp = sc.add_parser("generate", help="generate a seeded scene")
    add_common(sp, scene=False)
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
    add_common(sp)
    sp.add_argument("-o", "--output", required=True, help="PNG to write")
    sp.add_argument("--group", type=int, nargs="+")
    sp.add_argument("--candidates", action="store_true", help="overlay candidates coloured by verdict")
    sp.add_argument("--grasp", type=float, nargs=3, metavar=("X", "Y", "THETA"), help="draw this grasp")
    sp.add_argument("--top", type=int, default=3, help="S regions of the top N passing candidates")
    sp.add_argument("--positions", type=int, default=70)
    sp.add_argument("--orientations", type=int, default=7)
    sp.set_defaults(func=cmd_scene_show)

    sp = sub.add_parser("check", help="the two necessary conditions for one grasp")
    add_common(sp)
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
    add_common(sp)
    sp.add_argument("--group", type=int, nargs="+")
    sp.add_argument("--positions", type=int, default=70, help="Np")
    sp.add_argument("--orientations", type=int, default=7, help="Ntheta")
    sp.add_argument("--limit", type=int, default=20, help="rows in the text table")
    sp.add_argument("--all", action="store_true", help="include colliding candidates in the text table")
    sp.set_defaults(func=cmd_candidates)

    sp = sub.add_parser("plan", help="plan a grasp for a group (GraspPlanner, Alg. 2)")
    add_common(sp)
    sp.add_argument("--group", type=int, nargs="+")
    sp.add_argument("--method", default="gp", help="gp, rand-phys, rank-phys, rand-fil-phys or single")
    sp.add_argument("--seed", type=int, default=0, help="for the randomised methods")
    sp.add_argument("--max-physics", type=int, help="stop after this many physics checks")
    sp.set_defaults(func=cmd_plan)

    sp = sub.add_parser("demo", help="the planner's geometry on example scenes (table + picture)")
    sp.add_argument("--out", default="out/demo")
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_demo)


def cmd_shapes(args) -> int:
    lib = library(args)
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
    emit(args, {"shapes": recs, "inventories": lib.inventories}, format_table(rows))
    return 0


def cmd_scene_generate(args) -> int:
    from mog_drake.scenes import ClutterParams, cluttered_scene, row_scene

    rng = np.random.default_rng(args.seed)
    lib = library(args)
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
        emit(args, doc, f"wrote {args.output}: {len(scene)} objects ({args.kind}, seed {args.seed})")
    else:
        import yaml

        emit(args, doc, yaml.safe_dump(scene.to_dict(), sort_keys=False, default_flow_style=None))
    return 0


def cmd_scene_show(args) -> int:
    from mog_drake import plotting
    from mog_drake.geometry import GripperGeometry, candidate_grasps, evaluate_grasps, rank_grasp_cands

    scene = load_scene(args)
    gripper = GripperGeometry()
    group, _ = resolve_group(scene, args.group, gripper)
    ev = order = None
    if args.candidates:
        polys = scene.polygons()
        ev = evaluate_grasps(
            polys, group, candidate_grasps(polys, group, args.positions, args.orientations), gripper
        )
        order = rank_grasp_cands(ev)
    grasp = grasp_arg(args.grasp) if args.grasp else None
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
    emit(args, {"output": args.output, "group": list(group)}, f"wrote {args.output}")
    return 0


def cmd_check(args) -> int:
    from mog_drake.geometry import GripperGeometry, evaluate_grasps
    from mog_drake.geometry.conditions import record_lines

    scene = load_scene(args)
    gripper = GripperGeometry()
    group, source = resolve_group(scene, args.group, gripper)
    grasp = grasp_arg(args.grasp)
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
    emit(args, doc, "\n".join(lines))
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
    meshcat = meshcat_of(args)
    res = DrakeVerifier(sc.verifier, physics=physics, meshcat=meshcat).check(scene, group, grasp)
    if args.record:
        write_atomic(args.record, meshcat.StaticHtml())
    return res


def cmd_candidates(args) -> int:
    from mog_drake.geometry import GripperGeometry, candidate_grasps, evaluate_grasps, rank_grasp_cands
    from mog_drake.geometry.conditions import candidate_rows

    scene = load_scene(args)
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
    emit(args, doc, text)
    return 0


def cmd_plan(args) -> int:
    from mog_drake.planning.planner import GraspConfig, GraspPlanner
    from mog_drake.sim.verifier import DrakeVerifier

    scene = load_scene(args)
    group, source = resolve_group(scene, args.group)
    planner = GraspPlanner(DrakeVerifier(), GraspConfig(method=args.method, max_physics=args.max_physics))
    res = planner.plan(scene, group, rng=np.random.default_rng(args.seed))
    doc = {"scene": args.scene, "group_source": source, **res.to_dict()}
    emit(args, doc, res.text().replace(f"group {list(res.group)}", f"group {list(res.group)} ({source})", 1))
    return 0


def cmd_demo(args) -> int:
    """The planner's geometry on two example scenes: a table and a picture each."""
    from mog_drake.experiments.geometry_demo import geometry_demo

    doc, text = geometry_demo(args.out, args.seed)
    emit(args, doc, text.strip())
    return 0
