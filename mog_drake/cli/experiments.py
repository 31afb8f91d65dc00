"""The paper's experiments (resumable sweeps) and the benchmarks."""

from __future__ import annotations

from mog_drake.cli.common import emit
from mog_drake.experiments.bench import BENCHES
from mog_drake.planning.config import MODES


def add_sweep(sp) -> None:
    """What every sweep takes: its seed, folder, workers and output."""
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument("--out", required=True, help="output folder (resumes what it holds)")
    sp.add_argument("--jobs", type=int, help="parallel processes (default: all cores)")
    sp.add_argument("--ray", metavar="ADDRESS", help="run on an existing Ray cluster")
    sp.add_argument("--json", action="store_true")
    sp.add_argument("--summary-only", action="store_true", help="summarise what is done; run nothing")
    sp.set_defaults(func=cmd_eval)


def add_parsers(sub) -> None:
    ev = sub.add_parser("eval", help="the paper's experiments").add_subparsers(
        dest="experiment", required=True
    )
    for name, helptext in (
        ("conditions", "necessary conditions vs physics (Sec. 7.2)"),
        ("planner", "GP vs its baselines (Sec. 7.3)"),
    ):
        sp = ev.add_parser(name, help=helptext)
        add_sweep(sp)
        sp.add_argument("--classes", default="2-7", help="row classes, e.g. 2-7 or 2,4")
        sp.add_argument("--scenes-per-class", type=int, default=50)
        sp.add_argument("--positions", type=int, default=70, help="Np")
        sp.add_argument("--orientations", type=int, default=7, help="Ntheta")
        if name == "planner":
            sp.add_argument("--methods", default="gp,rand-phys,rank-phys,rand-fil-phys")
            sp.add_argument(
                "--max-physics", type=int, help="cap physics checks per plan (speed-ups: lower bounds)"
            )
    sp = ev.add_parser("picking", help="multi- vs single-object picking on cluttered tables (Table 1)")
    add_sweep(sp)
    sp.add_argument("--scenes", type=int, default=20)
    sp.add_argument("--modes", default="mog,sog")
    sp.add_argument("--objects", type=int, default=33, help="objects per table (the isrr33 inventory)")
    sp.add_argument("--time-limit", type=float, default=900.0, help="simulated robot seconds per table")
    sp.add_argument(
        "--scenario", help="scenario YAML every run uses (the sweep sets scene, time, mode, seed)"
    )
    sp.add_argument("--compare", metavar="DIR", help="another picking sweep's folder (A): paired differences")

    sp = sub.add_parser("bench", help="benchmarks that print a table")
    sp.add_argument("what", choices=BENCHES)
    sp.add_argument(
        "--scenes", type=int, default=20, help="scenes per class; tables (perception, replanning)"
    )
    sp.add_argument(
        "--tables", type=int, default=3, help="verifier: 33-object tables whose checks are replayed"
    )
    sp.add_argument("--out", help="verifier: folder for the scenes of the disagreements, to replay")
    sp.add_argument("--toppled", type=int, default=0, help="perception: bars laid on their side per table")
    sp.add_argument("--scenario", help="perception: a scenario's cell; replanning: its planner")
    sp.add_argument(
        "--depth-noise",
        metavar="LEVELS",
        help="perception: depth noise levels, comma-separated, in times the D435's RMS (default: the scenario's)",
    )
    sp.add_argument(
        "--camera-height",
        type=float,
        metavar="M",
        help="perception: the camera's height above the table in m (default: the scenario's, 0.8)",
    )
    sp.add_argument(
        "--mode", choices=MODES, help="replanning: the planner's mode (the scenario's when not given)"
    )
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_bench)


def cmd_eval(args) -> None:
    from mog_drake.experiments.evaluate import evaluate

    options = {k: v for k, v in vars(args).items() if k not in ("func", "command", "experiment", "json")}
    emit(args, *evaluate(args.experiment, progress=not args.json, **options))


def cmd_bench(args) -> None:
    from mog_drake.experiments import bench

    given = dict(tables=args.tables, out=args.out or "out/bench_verifier")
    emit(
        args,
        *bench.run(
            args.what,
            args.scenes,
            args.seed,
            args.toppled,
            not args.json,
            scenario=args.scenario,
            mode=args.mode,
            noise_levels=_levels(args.depth_noise),
            camera_height=args.camera_height,
            **given,
        ),
    )


def _levels(text: str | None):
    """--depth-noise LEVELS: non-negative numbers, comma-separated."""
    if text is None:
        return None
    from mog_drake.errors import MogError

    try:
        levels = [float(v) for v in text.split(",")]
    except ValueError:
        raise MogError(
            f"--depth-noise must be numbers separated by commas, e.g. 1,2,3, got {text!r}"
        ) from None
    if not levels or not all(0 <= v <= 10 for v in levels):
        raise MogError(f"--depth-noise levels must be in [0, 10] (times the D435's RMS), got {text!r}")
    return levels
