"""The object library: convex prism shapes (models/shapes.yaml), their resting variants."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
import yaml

from mog_drake.errors import MogError
from mog_drake.files import model_path, read_text
from mog_drake.geometry.polygon import (
    edge_directions,
    final_diameters,
    polygon_area,
    validate_convex_polygon,
)

DEFAULT_SHAPES_FILE = model_path("shapes.yaml")
#: A shape is a tabletop object: its vertices within this distance of its origin, its height
#: at most this (m). Larger numbers are typos, and break the physics.
MAX_SHAPE_SIZE = 0.5
#: ... and at least this tall (m): thinner is a sheet, not a prism the fingers can close on,
#: and its contact is ill-conditioned.
MIN_SHAPE_HEIGHT = 0.002


@dataclass(frozen=True)
class Shape:
    """A convex polygonal prism of the library. Vertices CCW in the body frame (m)."""

    name: str
    vertices: np.ndarray
    height: float
    density: float
    color: tuple[float, float, float, float]
    final_diameters: np.ndarray
    d_fmin: float
    min_width_normal: np.ndarray  # body-frame unit normal along which the width is d_fmin

    @property
    def sides(self) -> int:
        return len(self.vertices)

    @property
    def area(self) -> float:
        return polygon_area(self.vertices)

    @property
    def mass(self) -> float:
        return self.area * self.height * self.density

    @cached_property  # asked for every object of every polygon set
    def radius(self) -> float:
        return float(np.linalg.norm(self.vertices, axis=1).max())

    @property
    def reach(self) -> float:
        """The farthest any point of the prism lies from its body origin (at the centre of its
        base), however it is tilted (m)."""
        return float(np.hypot(self.radius, self.height))

    def to_record(self) -> dict:
        return {
            "name": self.name,
            "sides": self.sides,
            "vertices": self.vertices.tolist(),
            "height": self.height,
            "density": self.density,
            "mass": self.mass,
            "color": list(self.color),
            "d_fmin": self.d_fmin,
            "final_diameters": self.final_diameters.tolist(),
        }


def make_shape(name: str, spec: dict) -> Shape:
    """Builds and validates a library shape from its YAML mapping."""
    if not isinstance(spec, dict):
        raise MogError(f"shape '{name}': expected a mapping with vertices, height, density, color")
    unknown = set(spec) - {"vertices", "height", "density", "color"}
    if unknown:
        raise MogError(f"shape '{name}': unknown field(s) {sorted(unknown)}")
    if "vertices" not in spec or "height" not in spec:
        raise MogError(f"shape '{name}': needs 'vertices' and 'height'")
    verts = validate_convex_polygon(spec["vertices"], name)
    # Express the body frame about the polygon's centroid-free origin as given: poses refer to
    # the body origin, which the library defines.
    if float(np.abs(verts).max()) > MAX_SHAPE_SIZE:
        raise MogError(f"shape '{name}': its vertices must lie within {MAX_SHAPE_SIZE} m of its origin")
    height = _positive(spec["height"], f"shape '{name}': height", MAX_SHAPE_SIZE)
    if height < MIN_SHAPE_HEIGHT:
        raise MogError(f"shape '{name}': height must be at least {MIN_SHAPE_HEIGHT} m, got {height:g}")
    density = _positive(spec.get("density", 1000.0), f"shape '{name}': density", 1e5)
    color = spec.get("color", [0.6, 0.6, 0.6, 1.0])
    try:
        color = tuple(float(c) for c in color)
    except (TypeError, ValueError):
        raise MogError(f"shape '{name}': color must be 3 or 4 numbers in [0, 1]") from None
    if len(color) == 3:
        color = (*color, 1.0)
    if len(color) != 4 or not all(0.0 <= c <= 1.0 for c in color):
        raise MogError(f"shape '{name}': color must be 3 or 4 numbers in [0, 1]")
    diam = final_diameters(verts)
    # Normal of the edge whose antipodal width is d_fmin.
    _, normals = edge_directions(verts)
    widths = np.array([float(((verts - verts[i]) @ (-normals[i])).max()) for i in range(len(verts))])
    return Shape(
        name=name,
        vertices=verts,
        height=height,
        density=density,
        color=color,
        final_diameters=diam,
        d_fmin=float(diam.min()),
        min_width_normal=normals[int(np.argmin(widths))],
    )


def _box_dims(vertices: np.ndarray) -> tuple[float, float] | None:
    """Side lengths of a rectangle's polygon, or None if it is not a rectangle."""
    v = np.asarray(vertices, dtype=float)
    if len(v) != 4:
        return None
    e = np.roll(v, -1, axis=0) - v
    lengths = np.linalg.norm(e, axis=1)
    cos = np.abs((e * np.roll(e, -1, axis=0)).sum(1)) / (lengths * np.roll(lengths, -1))
    if np.any(cos > 1e-6):
        return None
    return float(lengths[0]), float(lengths[1])


def _positive(v, what: str, upper: float = math.inf) -> float:
    if isinstance(v, bool):
        raise MogError(f"{what} must be a number, got {v!r}")
    try:
        f = float(v)
    except (TypeError, ValueError, OverflowError):
        raise MogError(f"{what} must be a number, got {v!r}") from None
    if not math.isfinite(f) or f <= 0:
        raise MogError(f"{what} must be a positive finite number, got {v!r}")
    if f > upper:
        raise MogError(f"{what} must be at most {upper:g}, got {v!r}")
    return f


MAX_YAML_ALIASES = 100  # a scene or scenario needs none: aliases nest into a billion copies
MAX_YAML_DEPTH = 40  # a scenario nests five deep


# YAML's C scanner and loader where PyYAML has them: its Python ones take seconds per 100 kB.
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def check_yaml(text: str, where: str, max_values: int | None = None) -> None:
    """Refuses YAML that would expand past memory or recursion before it is built: more than
    MAX_YAML_ALIASES aliases, or collections nested deeper than MAX_YAML_DEPTH, or (with
    ``max_values``) more scalars than that: one scan of its tokens, nothing expanded."""
    aliases = depth = values = 0
    try:
        for token in yaml.scan(text, Loader=_LOADER):
            if isinstance(token, yaml.ScalarToken) and max_values is not None:
                values += 1
                if values > max_values:
                    raise MogError(f"{where}: more than {max_values:,} YAML values")
            elif isinstance(token, yaml.AliasToken):
                aliases += 1
                if aliases > MAX_YAML_ALIASES:
                    raise MogError(f"{where}: more than {MAX_YAML_ALIASES} YAML aliases")
            elif isinstance(
                token,
                (
                    yaml.BlockMappingStartToken,
                    yaml.BlockSequenceStartToken,
                    yaml.FlowMappingStartToken,
                    yaml.FlowSequenceStartToken,
                ),
            ):
                depth += 1
                if depth > MAX_YAML_DEPTH:
                    raise MogError(f"{where}: YAML nested more than {MAX_YAML_DEPTH} deep")
            elif isinstance(token, (yaml.BlockEndToken, yaml.FlowMappingEndToken, yaml.FlowSequenceEndToken)):
                depth -= 1
    except yaml.YAMLError:
        return  # the loader that follows names the syntax error


def read_yaml(path: Path) -> dict:
    path = Path(path)
    text = read_text(path, "YAML file")
    check_yaml(text, str(path))
    try:
        data = yaml.load(text, Loader=_LOADER)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" line {mark.line + 1}" if mark is not None else ""
        raise MogError(f"{path}:{where} is not valid YAML") from None
    if not isinstance(data, dict):
        raise MogError(f"{path}: expected a YAML mapping at the top level")
    return data


@dataclass
class ShapeLibrary:
    """Named shapes and named inventories (shape -> count)."""

    shapes: dict[str, Shape]
    inventories: dict[str, dict[str, int]] = field(default_factory=dict)
    bars: tuple[str, ...] = ("thin_bar", "thick_bar")

    def report(self) -> tuple[dict, str]:
        """Every shape's figures (a document, and a table in mm and g) and the inventories."""
        from mog_drake.tables import format_table

        recs = [self[n].to_record() for n in self.shapes]
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
        return {"shapes": recs, "inventories": self.inventories}, format_table(rows)

    @classmethod
    def load(cls, *extra_files: str | Path, base: str | Path | None = DEFAULT_SHAPES_FILE) -> ShapeLibrary:
        """The default library, extended (and overridden by name) by ``extra_files``."""
        lib = cls(shapes={}, inventories={})
        for f in ([base] if base else []) + [Path(p) for p in extra_files]:
            lib._merge(read_yaml(Path(f)), Path(f))
        return lib

    def _merge(self, data: dict, path: Path) -> None:
        unknown = set(data) - {"shapes", "inventories", "bars"}
        if unknown:
            raise MogError(f"{path}: unknown top-level key(s) {sorted(unknown)}")
        shapes = data.get("shapes", {}) or {}
        if not isinstance(shapes, dict):
            raise MogError(f"{path}: 'shapes' must be a mapping of name -> shape")
        for name, spec in shapes.items():
            self.shapes[str(name)] = make_shape(str(name), spec)
        inventories = data.get("inventories", {}) or {}
        if not isinstance(inventories, dict):
            raise MogError(f"{path}: 'inventories' must be a mapping of name -> {{shape: count}}")
        for inv_name, inv in inventories.items():
            if not isinstance(inv, dict):
                raise MogError(f"{path}: inventory '{inv_name}' must map shape names to counts")
            for shape, count in inv.items():
                if shape not in self.shapes:
                    raise MogError(f"{path}: inventory '{inv_name}' names unknown shape '{shape}'")
                if not isinstance(count, int) or count < 0:
                    raise MogError(
                        f"{path}: inventory '{inv_name}': count of '{shape}' must be a whole number >= 0"
                    )
            self.inventories[str(inv_name)] = {str(k): int(v) for k, v in inv.items()}
        if "bars" in data:
            bars = data["bars"]
            if not isinstance(bars, list) or not all(isinstance(b, str) and b in self.shapes for b in bars):
                raise MogError(f"{path}: 'bars' must be a list of the library's shape names, got {bars!r}")
            self.bars = tuple(bars)

    def __getitem__(self, name: str) -> Shape:
        shape = self.shapes.get(name) or self.resting_variants().get(name)
        if shape is None:
            raise MogError(f"unknown shape '{name}' (known: {', '.join(sorted(self.shapes))})")
        return shape

    def resting_variants(self) -> dict[str, Shape]:
        """A rectangular prism knocked over is again a rectangular prism: ``NAME:on_side``
        lies on its long side face (footprint length x height, as tall as it was wide) and
        ``NAME:on_end`` stands on its end face. Same box, same mass, same colour, so the
        planner and the verifier treat a toppled bar exactly. Cubes (no new box) are skipped.
        Perception looks for these; scene generators never draw them."""
        key = tuple(sorted(self.shapes))
        if getattr(self, "_variants_key", None) != key:
            out: dict[str, Shape] = {}
            for name, shape in self.shapes.items():
                dims = _box_dims(shape.vertices)
                if dims is None:
                    continue
                a, b = max(dims), min(dims)
                h = shape.height
                seen = {(round(b, 5), round(a, 5), round(h, 5))}
                for suffix, (w, d, top) in (("on_side", (a, h, b)), ("on_end", (b, h, a))):
                    box = (*sorted((round(w, 5), round(d, 5))), round(top, 5))
                    if box in seen:
                        continue  # the same box as a pose already listed
                    seen.add(box)
                    half = np.array([w, d]) / 2
                    verts = [
                        [half[0], half[1]],
                        [-half[0], half[1]],
                        [-half[0], -half[1]],
                        [half[0], -half[1]],
                    ]
                    out[f"{name}:{suffix}"] = make_shape(
                        f"{name}:{suffix}",
                        {
                            "vertices": verts,
                            "height": top,
                            "density": shape.density,
                            "color": list(shape.color),
                        },
                    )
            self._variants, self._variants_key = out, key
        return self._variants

    def base_shape(self, name: str) -> str:
        """The library shape a resting variant is a pose of (the name itself otherwise)."""
        return name.split(":", 1)[0]

    def inventory(self, name: str) -> list[str]:
        """The inventory as a list of shape names, one entry per object, in a fixed order."""
        if name not in self.inventories:
            raise MogError(f"unknown inventory '{name}' (known: {', '.join(sorted(self.inventories))})")
        return [s for s, n in self.inventories[name].items() for _ in range(n)]

    @property
    def irregular(self) -> list[str]:
        return [n for n in self.shapes if n not in self.bars]


_DEFAULT_LIBRARY: ShapeLibrary | None = None


def default_library() -> ShapeLibrary:
    global _DEFAULT_LIBRARY
    if _DEFAULT_LIBRARY is None:
        _DEFAULT_LIBRARY = ShapeLibrary.load()
    return _DEFAULT_LIBRARY
