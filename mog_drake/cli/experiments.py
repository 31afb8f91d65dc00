"""The paper's experiments (resumable sweeps) and the benchmarks."""

from __future__ import annotations

from mog_drake.cli.common import emit
from mog_drake.cli.geometry import add_grid
from mog_drake.experiments.bench import BENCHES
from mog_drake.planning.config import MODES


def add_sweep(sp) -> None:
    """What every sweep takes: its seed, folder, workers and output."""
    sp.add_argument(
        "--seed",
        type=int,
        default=0,
        help="the sweep's seed, a whole number: its scenes' seeds follow from it (default: 0)",
    )
    sp.add_argument("--out", required=True, help="output folder; a sweep resumes what it holds")
    sp.add_argument(
        "--jobs",
        type=int,
        help="parallel processes on this machine (default: all cores). Picking sweeps take perception's and "
        "planning's CPU time as their latency (latency.mode cpu, unless the scenario sets it), so their "
        "results do not depend on the machine's load",
    )
    sp.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="run on a Ray cluster instead: auto (this machine's) or HOST:PORT as `ray start --head` prints it "
        "(default: none, the processes of --jobs)",
    )
    sp.add_argument("--json", action="store_true", help="print one JSON document instead of text")
    sp.add_argument(
        "--summary-only", action="store_true", help="summarise what the folder holds; run nothing"
    )
    sp.set_defaults(func=cmd_eval)


def add_parsers(sub) -> None:
    ev = sub.add_parser("eval", help="the paper's experiments, as resumable sweeps").add_subparsers(
        dest="experiment", required=True
    )
    for name, helptext in (
        ("conditions", "the necessary conditions against physics on row scenes (the paper's Sec. 7.2)"),
        ("planner", "GP against its baselines on row scenes: time and physics checks (Sec. 7.3)"),
    ):
        sp = ev.add_parser(name, help=helptext)
        add_sweep(sp)
        sp.add_argument(
            "--classes", default="2-7", help="row classes (objects per row), e.g. 2-7 or 2,4 (default: 2-7)"
        )
        sp.add_argument(
            "--scenes-per-class", type=int, default=50, help="seeded scenes per class (default: 50)"
        )
        add_grid(sp)
        if name == "planner":
            sp.add_argument(
                "--methods",
                default="gp,rand-phys,rank-phys,rand-fil-phys",
                help="methods, comma-separated (default: gp,rand-phys,rank-phys,rand-fil-phys)",
            )
            sp.add_argument(
                "--max-physics",
                type=int,
                help="cap the physics checks of each plan: the baselines' times become lower bounds (default: no cap)",
            )
    sp = ev.add_parser("picking", help="multi- against single-object picking on cluttered tables (Table 1)")
    add_sweep(sp)
    sp.add_argument("--scenes", type=int, default=20, help="seeded tables (default: 20)")
    sp.add_argument(
        "--modes", default="mog,sog", help="modes, comma-separated: mog, sog, push-mog (default: mog,sog)"
    )
    sp.add_argument(
        "--objects",
        type=int,
        default=33,
        help="objects per table, 1-33 of the isrr33 inventory (default: 33)",
    )
    sp.add_argument(
        "--time-limit", type=float, default=900.0, help="s of simulated robot time per table (default: 900)"
    )
    sp.add_argument(
        "--scenario",
        help="scenario YAML (or a shipped one's name) every run uses; the sweep sets its table, time limit, "
        "mode and seed (default: the built-in one)",
    )
    sp.add_argument(
        "--compare",
        metavar="DIR",
        help="another picking sweep's folder, the same tables: paired differences (default: none)",
    )

    sp = sub.add_parser(
        "bench", help="benchmarks that print a table: " + "; ".join(f"{k}: {v}" for k, v in BENCHES.items())
    )
    sp.add_argument("what", choices=list(BENCHES), help="which benchmark")
    sp.add_argument(
        "--scenes",
        type=int,
        default=20,
        help="geometry, verifier: row scenes per class; perception, replanning, rest: tables (default: 20)",
    )
    sp.add_argument(
        "--tables",
        type=int,
        default=3,
        help="verifier: 33-object tables whose checks are replayed (default: 3)",
    )
    sp.add_argument(
        "--out",
        help="verifier: folder for the scenes of the disagreements, to replay (default: out/bench_verifier)",
    )
    sp.add_argument(
        "--toppled", type=int, default=0, help="perception: bars laid on their side per table (default: 0)"
    )
    sp.add_argument(
        "--scenario",
        help="perception: the cell (camera, realism, perception); replanning: the planner (default: the built-in one)",
    )
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
        "--calibrate",
        action="store_true",
        help="perception: the camera's pose from a rendered calibration board in each table's world, not the scenario's",
    )
    sp.add_argument("--mode", choices=MODES, help="replanning: the planner's mode (default: the scenario's)")
    sp.add_argument("--seed", type=int, default=0, help="the first scene's or table's seed (default: 0)")
    sp.add_argument("--json", action="store_true", help="print one JSON document instead of text")
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
            calibrate=args.calibrate,
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
