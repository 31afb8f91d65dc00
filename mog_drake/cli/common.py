"""What every command shares: the one-line parser, argument checks, scenes and shapes from
their files, and printing text or one JSON document."""

from __future__ import annotations

import argparse
import json
import math
import re
from pathlib import Path

from mog_drake.errors import MogError
from mog_drake.files import check_writable, plain
from mog_drake.planning.config import MAX_ORIENTATIONS, MAX_POSITIONS


class UsageError(Exception):
    pass


class Parser(argparse.ArgumentParser):
    """argparse, with its errors on one line (`mog-drake: error: ...`, exit 2) and numbers in
    exponent form (-1e-3) read as numbers, not options. Subparsers are of this class too."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message):
        raise UsageError(" ".join(str(message).split()))


def add_common(sp, scene: bool = True) -> None:
    """--json, --shapes and (``scene``) the scene file argument."""
    sp.add_argument("--json", action="store_true", help="print one JSON document instead of text")
    sp.add_argument(
        "--shapes",
        action="append",
        metavar="FILE",
        help="shapes of your own, a YAML laid out like models/shapes.yaml (repeatable; default: the library alone)",
    )
    if scene:
        sp.add_argument("scene", help="scene YAML file (`scene generate` writes them)")


def library(args):
    from mog_drake.scenes import ShapeLibrary, default_library

    files = getattr(args, "shapes", None) or []
    return ShapeLibrary.load(*files) if files else default_library()


def load_scene(args):
    from mog_drake.scenes import Scene

    return Scene.load(args.scene, library(args) if getattr(args, "shapes", None) else None)


def emit(args, doc: dict, text: str) -> None:
    print(json.dumps(plain(doc), indent=2, allow_nan=False) if getattr(args, "json", False) else text)


GRASP_HELP = "a grasp in the table frame: its centre in mm and the closing axis in degrees, as `candidates` prints them"


def grasp_arg(values, scene=None):
    """``--grasp X_MM Y_MM THETA_DEG`` (what `candidates` prints) as (x, y, theta) in m and
    rad. With ``scene``: refused unless its centre lies on the scene's table."""
    import numpy as np

    g = np.array(values, dtype=float)
    if not np.all(np.isfinite(g)):
        raise MogError(f"--grasp must be three finite numbers X_MM Y_MM THETA_DEG, got {values}")
    g = np.array([g[0] / 1e3, g[1] / 1e3, math.radians(g[2])])
    if scene is not None:
        x0, x1, y0, y1 = scene.table
        if not (x0 <= g[0] <= x1 and y0 <= g[1] <= y1):
            raise MogError(
                f"--grasp centre ({values[0]:g}, {values[1]:g}) mm is off the scene's table "
                f"(x {x0 * 1e3:g} to {x1 * 1e3:g} mm, y {y0 * 1e3:g} to {y1 * 1e3:g} mm): "
                "--grasp takes mm and degrees, as `candidates` prints them"
            )
    return g


def meshcat_of(args):
    """A Meshcat for --meshcat (its address on stderr) or --record, else None."""
    if not (args.meshcat or args.record):
        return None
    from mog_drake.station.sim import start_meshcat

    return start_meshcat(args.meshcat)


AT_LEAST_1 = (
    "positions orientations limit scenes objects clusters top candidates scenes_per_class jobs max_physics"
)
POSITIVE = ("time_limit", "timeout", "move_timeout", "window", "force")
MOST = {"positions": MAX_POSITIONS, "orientations": MAX_ORIENTATIONS}
SUFFIXES = {"output": (".png", ".svg", ".pdf", ".jpg", ".jpeg"), "record": (".html",)}


def check_args(args) -> None:
    """Refuses bad numbers and output paths before anything runs."""
    for name in AT_LEAST_1.split():
        v = getattr(args, name, None)
        if v is not None and not isinstance(v, bool) and v < 1:
            raise MogError(f"--{name.replace('_', '-')} must be at least 1, got {v}")
    for name, most in MOST.items():
        if (getattr(args, name, None) or 0) > most:
            raise MogError(
                f"--{name} must be at most {most:,} (the grid's memory and time), got {getattr(args, name):,}"
            )
    if args.command == "gripper":
        if not args.ip.strip():
            raise MogError("--ip must name the gripper's host (the UR controller's address)")
        if not 1 <= args.port <= 65535:
            raise MogError(f"--port must be a TCP port (1-65535), got {args.port}")
    if (getattr(args, "tables", None) or 0) < 0:
        raise MogError(f"--tables must be at least 0, got {args.tables}")
    seed = getattr(args, "seed", None)
    if seed is not None and not 0 <= seed < 2**63:
        raise MogError(f"--seed must be a whole number >= 0, got {seed}")
    for name in POSITIVE:
        v = getattr(args, name, None)
        if v is not None and not (math.isfinite(v) and v > 0):
            raise MogError(f"--{name.replace('_', '-')} must be a positive number, got {v}")
    for name, suffixes in SUFFIXES.items():
        v = getattr(args, name, None)
        if not v:
            continue
        path = Path(v)
        if path.is_dir():
            raise MogError(f"--{name} {v} is a directory: give a file name")
        if name == "output" and args.command == "diagram":
            suffixes = (*suffixes, ".dot")
        if path.suffix.lower() not in suffixes and not (
            args.command == "scene" and args.scene_command == "generate"
        ):
            raise MogError(
                f"--{name} {v}: unknown file type {path.suffix or '(none)'} (use {', '.join(suffixes)})"
            )
        check_writable(path, f"--{name}")
    out = getattr(args, "out", None)
    if out and Path(out).exists() and not Path(out).is_dir():
        raise MogError(f"--out {out} is a file: give a folder")
