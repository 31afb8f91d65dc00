"""What every command shares: the one-line parser, argument checks, scenes and shapes from
their files, and printing text or one JSON document."""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from pathlib import Path

import numpy as np

from mog_drake.errors import MogError
from mog_drake.outputs import check_writable


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
    sp.add_argument("--json", action="store_true", help="print one JSON document")
    sp.add_argument("--shapes", action="append", metavar="FILE", help="extra shape library YAML (repeatable)")
    if scene:
        sp.add_argument("scene", help="scene YAML file")


def library(args):
    from mog_drake.scenes import ShapeLibrary, default_library

    files = getattr(args, "shapes", None) or []
    return ShapeLibrary.load(*files) if files else default_library()


def load_scene(args):
    from mog_drake.scenes import Scene

    lib = library(args) if getattr(args, "shapes", None) else None
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


def emit(args, doc: dict, text: str) -> None:
    if getattr(args, "json", False):
        print(json.dumps(plain(doc), indent=2, allow_nan=False))
    else:
        print(text)


def grasp_arg(values) -> np.ndarray:
    g = np.array(values, dtype=float)
    if not np.all(np.isfinite(g)):
        raise MogError(f"--grasp must be three finite numbers X Y THETA, got {values}")
    return g


def meshcat_of(args):
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


IMAGE_SUFFIXES = (".png", ".svg", ".pdf", ".jpg", ".jpeg")


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
