"""Commands on one scene at a time: the shape library, scenes, the necessary conditions for a
grasp, candidates, GraspPlanner, and the geometry demo."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from mog_drake.cli.common import GRASP_HELP, add_common, emit, grasp_arg, library, load_scene, meshcat_of
from mog_drake.files import write_atomic

GROUP_HELP = (
    "the group: object indices in the scene file, 0-based (default: the file's group, or all its objects)"
)


def add_parsers(sub) -> None:
    sp = sub.add_parser("shapes", help="list the object library: each shape's size, mass and final diameters")
    add_common(sp, scene=False)
    sp.set_defaults(func=cmd_shapes)

    sc = sub.add_parser("scene", help="generate or draw scenes").add_subparsers(
        dest="scene_command", required=True
    )
    sp = sc.add_parser(
        "generate", help="generate a seeded scene: one of the paper's rows, or a cluttered table"
    )
    add_common(sp, scene=False)
    sp.add_argument(
        "--kind",
        choices=["row", "cluttered"],
        default="row",
        help="a row along the closing axis, or a cluttered table (default: row)",
    )
    sp.add_argument(
        "--class",
        dest="row_class",
        type=int,
        help="row: the paper's class, its number of objects, 1-7 (required with --kind row; no default)",
    )
    sp.add_argument("--objects", type=int, help="cluttered: how many objects (default: the whole inventory)")
    sp.add_argument(
        "--inventory",
        default="isrr33",
        help="cluttered: the library's inventory to draw from (default: isrr33)",
    )
    sp.add_argument(
        "--clusters",
        type=int,
        default=4,
        help="cluttered: clusters the objects are dropped around (default: 4)",
    )
    sp.add_argument("--seed", type=int, default=0, help="the generator's seed, a whole number (default: 0)")
    sp.add_argument("-o", "--output", help="scene YAML to write (default: print it)")
    sp.set_defaults(func=cmd_scene_generate)

    sp = sc.add_parser("show", help="draw a scene to a picture")
    add_common(sp)
    sp.add_argument("-o", "--output", required=True, help="picture to write: .png, .svg, .pdf or .jpg")
    sp.add_argument("--group", type=int, nargs="+", metavar="INDEX", help=GROUP_HELP)
    sp.add_argument(
        "--candidates", action="store_true", help="overlay the grasp candidates, coloured by verdict"
    )
    sp.add_argument(
        "--grasp",
        type=float,
        nargs=3,
        metavar=("X_MM", "Y_MM", "THETA_DEG"),
        help=f"draw {GRASP_HELP} (default: none)",
    )
    sp.add_argument(
        "--top",
        type=int,
        default=3,
        help="draw the jaws' region S of the N best passing candidates (default: 3)",
    )
    add_grid(sp)
    sp.set_defaults(func=cmd_scene_show)

    sp = sub.add_parser(
        "check", help="the two necessary conditions for one grasp, and optionally its physics check"
    )
    add_common(sp)
    sp.add_argument(
        "--grasp", type=float, nargs=3, metavar=("X_MM", "Y_MM", "THETA_DEG"), required=True, help=GRASP_HELP
    )
    sp.add_argument("--group", type=int, nargs="+", metavar="INDEX", help=GROUP_HELP)
    sp.add_argument(
        "--simulate", action="store_true", help="also run the physics check: close, lift 0.15 m, hold"
    )
    sp.add_argument(
        "--meshcat", action="store_true", help="show the physics check live in Meshcat (implies --simulate)"
    )
    sp.add_argument(
        "--record",
        metavar="HTML",
        help="write the physics check as a Meshcat replay, .html (implies --simulate; default: none)",
    )
    sp.add_argument("--force", type=float, help="grip force per jaw in N (default: the scenario's, 40)")
    sp.add_argument(
        "--scenario",
        help="scenario YAML, or a shipped one's name, whose physics check and gripper the simulation uses "
        "(default: the built-in one, the picking planner's check; row_check: the paper's row check, as plan uses)",
    )
    sp.set_defaults(func=cmd_check)

    sp = sub.add_parser("candidates", help="every grasp candidate of a group with its figures, ranked by A_T")
    add_common(sp)
    sp.add_argument("--group", type=int, nargs="+", metavar="INDEX", help=GROUP_HELP)
    add_grid(sp)
    sp.add_argument("--limit", type=int, default=20, help="rows in the text table (default: 20)")
    sp.add_argument("--all", action="store_true", help="list colliding candidates too")
    sp.set_defaults(func=cmd_candidates)

    sp = sub.add_parser(
        "plan",
        help="plan a grasp for a group: GraspPlanner (the paper's Alg. 2) or a baseline, checked in the paper's row check (models/row_check.yaml)",
    )
    add_common(sp)
    sp.add_argument("--group", type=int, nargs="+", metavar="INDEX", help=GROUP_HELP)
    sp.add_argument(
        "--method",
        default="gp",
        help="gp (the paper's GP), rand-phys, rank-phys, rand-fil-phys or single (default: gp)",
    )
    sp.add_argument(
        "--seed", type=int, default=0, help="the randomised methods' seed, a whole number (default: 0)"
    )
    sp.add_argument("--max-physics", type=int, help="stop after this many physics checks (default: no limit)")
    sp.set_defaults(func=cmd_plan)

    sp = sub.add_parser("demo", help="the planner's geometry on two example scenes: a table and a picture")
    sp.add_argument("--out", default="out/demo", help="folder for the pictures (default: out/demo)")
    sp.add_argument(
        "--seed",
        type=int,
        default=2,
        help="the example scenes' seed (default: 2, a row whose four objects one grasp takes)",
    )
    sp.add_argument("--json", action="store_true", help="print one JSON document instead of text")
    sp.set_defaults(func=cmd_demo)


def add_grid(sp) -> None:
    sp.add_argument(
        "--positions",
        type=int,
        default=70,
        help="Np, the candidate grid's positions over the group's bounding box (the paper's 70: 7 x 10; default: 70)",
    )
    sp.add_argument(
        "--orientations",
        type=int,
        default=7,
        help="Ntheta, closing-axis angles over 180 degrees (the paper's 7; default: 7)",
    )


def cmd_shapes(args) -> None:
    emit(args, *library(args).report())


def cmd_scene_generate(args) -> None:
    from mog_drake.scenes.generators import generate_scene

    scene = generate_scene(
        args.kind,
        args.seed,
        library(args),
        args.row_class,
        args.objects,
        args.inventory,
        clusters=args.clusters,
    )
    if args.shapes:
        scene.shapes_file = str(Path(args.shapes[-1]).resolve())
    doc = {"output": args.output, "objects": len(scene), "meta": scene.meta, "scene": scene.to_dict()}
    if args.output:
        scene.save(args.output)
        emit(args, doc, f"wrote {args.output}: {len(scene)} objects ({args.kind}, seed {args.seed})")
    else:
        emit(args, doc, scene.to_yaml())


def cmd_scene_show(args) -> None:
    from mog_drake.plotting import scene_picture

    scene = load_scene(args)
    group, _ = scene.chosen_group(args.group)
    grid = (args.candidates, args.positions, args.orientations)
    grasp = grasp_arg(args.grasp, scene) if args.grasp else None
    scene_picture(
        scene,
        group,
        args.output,
        *grid,
        top=args.top,
        grasp=grasp,
        title=f"{args.scene}  group {list(group)}",
    )
    emit(args, {"output": args.output, "group": list(group)}, f"wrote {args.output}")


def cmd_check(args) -> None:
    from mog_drake.geometry import GripperGeometry
    from mog_drake.geometry.report import check_report

    scene = load_scene(args)
    group, source = scene.chosen_group(args.group)
    grasp = grasp_arg(args.grasp, scene)
    doc, lines = check_report(scene, group, source, grasp, GripperGeometry())
    doc = {"scene": args.scene, **doc}
    if args.simulate or args.meshcat or args.record:
        from mog_drake.scenario import load_scenario
        from mog_drake.sim.verifier import verify_one

        sc = load_scenario(args.scenario)  # a bad file is refused before anything starts
        meshcat = meshcat_of(args)
        res = verify_one(sc, scene, group, grasp, args.force, meshcat)
        if args.record:
            write_atomic(args.record, meshcat.StaticHtml())
        doc["simulation"] = res.to_dict()
        lines += [res.text()] + ([f"replay     {args.record}"] if args.record else [])
    emit(args, doc, "\n".join(lines))
    if args.meshcat and sys.stdin.isatty():
        input("Meshcat is serving the replay; press Enter to quit. ")


def cmd_candidates(args) -> None:
    from mog_drake.geometry import GripperGeometry
    from mog_drake.geometry.report import candidates_report

    scene = load_scene(args)
    group, source = scene.chosen_group(args.group)
    doc, text = candidates_report(
        scene,
        group,
        source,
        GripperGeometry(),
        args.positions,
        args.orientations,
        limit=args.limit,
        all_rows=args.all,
    )
    emit(args, {"scene": args.scene, **doc}, text)


def cmd_plan(args) -> None:
    from mog_drake.planning.planner import GraspConfig, GraspPlanner
    from mog_drake.sim.verifier import row_verifier

    scene = load_scene(args)
    group, source = scene.chosen_group(args.group)
    planner = GraspPlanner(row_verifier(), GraspConfig(method=args.method, max_physics=args.max_physics))
    res = planner.plan(scene, group, rng=np.random.default_rng(args.seed))
    doc = {"scene": args.scene, "group_source": source, **res.to_dict()}
    emit(args, doc, res.text().replace(f"group {list(res.group)}", f"group {list(res.group)} ({source})", 1))


def cmd_demo(args) -> None:
    from mog_drake.experiments.geometry_demo import geometry_demo

    doc, text = geometry_demo(args.out, args.seed)
    emit(args, doc, text.strip())
