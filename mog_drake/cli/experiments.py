"""The paper's experiments (resumable sweeps) and the benchmarks."""

from __future__ import annotations

from pathlib import Path

from mog_drake.cli.common import emit
from mog_drake.errors import MogError
from mog_drake.experiments.bench import BENCHES
from mog_drake.planning.config import MODES


def add_parsers(sub) -> None:
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
        help="replanning: compare the defaults with planner.loop.decision_budget_s = this (s)",
    )
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_bench)


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
            objects=args.objects,
            time_limit=args.time_limit,
            jobs=jobs,
            ray_address=args.ray,
            progress=progress,
            scenario=scenario,
            compare_dir=args.compare,
        )
        text = picking_eval.report(summary, results, out, args.compare)
    elif args.experiment == "conditions":
        from mog_drake.experiments import conditions

        summary, _ = conditions.run(
            _parse_classes(args.classes),
            args.scenes_per_class,
            args.seed,
            out,
            jobs=jobs,
            ray_address=args.ray,
            progress=progress,
            n_positions=args.positions,
            n_orientations=args.orientations,
        )
        text = conditions.report(summary, out)
    else:
        from mog_drake.experiments import planning_eval
        from mog_drake.planning.config import METHODS

        methods = [m.strip() for m in args.methods.split(",") if m.strip()]
        bad = [m for m in methods if m not in METHODS]
        if bad or not methods:
            raise MogError(f"--methods: unknown {bad or args.methods} (known: {', '.join(METHODS)})")
        summary, _ = planning_eval.run(
            _parse_classes(args.classes),
            args.scenes_per_class,
            args.seed,
            out,
            methods=methods,
            jobs=jobs,
            ray_address=args.ray,
            max_physics=args.max_physics,
            progress=progress,
            n_positions=args.positions,
            n_orientations=args.orientations,
        )
        text = planning_eval.report(summary, out)
    emit(args, summary, text)
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
    emit(args, doc, text)
    return 0
