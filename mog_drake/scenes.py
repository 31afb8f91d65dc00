"""Object library, scenes, YAML I/O and seeded scene generators.

A scene is a list of objects (library shape, pose x, y, theta) lying on a table, in the table
frame (origin at the centre of the table top, z up). Units are SI.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import shapely
import yaml

from mog_drake.errors import MogError
from mog_drake.geometry.conditions import PolygonSet
from mog_drake.geometry.polygon import (
    edge_directions,
    final_diameters,
    polygon_area,
    transform,
    validate_convex_polygon,
)

MODELS_DIR = Path(os.environ.get("MOG_DRAKE_MODELS", Path(__file__).resolve().parent.parent / "models"))
DEFAULT_SHAPES_FILE = MODELS_DIR / "shapes.yaml"

#: Default table top (xmin, xmax, ymin, ymax) in m: objects must lie inside it.
DEFAULT_TABLE = (-0.25, 0.25, -0.25, 0.25)
#: Two objects may overlap by at most this area (m^2, = 1 mm^2) before a scene is refused.
DEFAULT_OVERLAP_TOL = 1e-6


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

    @property
    def radius(self) -> float:
        return float(np.linalg.norm(self.vertices, axis=1).max())

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
    height = _positive(spec["height"], f"shape '{name}': height")
    density = _positive(spec.get("density", 1000.0), f"shape '{name}': density")
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


def _positive(v, what: str) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise MogError(f"{what} must be a number, got {v!r}") from None
    if not math.isfinite(f) or f <= 0:
        raise MogError(f"{what} must be a positive finite number, got {v!r}")
    return f


def _read_yaml(path: Path) -> dict:
    path = Path(path)
    if not path.is_file():
        raise MogError(f"file not found: {path}")
    try:
        data = yaml.safe_load(path.read_text())
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

    @classmethod
    def load(cls, *extra_files: str | Path, base: str | Path | None = DEFAULT_SHAPES_FILE) -> ShapeLibrary:
        """The default library, extended (and overridden by name) by ``extra_files``."""
        lib = cls(shapes={}, inventories={})
        for f in ([base] if base else []) + [Path(p) for p in extra_files]:
            lib._merge(_read_yaml(Path(f)), Path(f))
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
        for inv_name, inv in (data.get("inventories", {}) or {}).items():
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
            self.bars = tuple(str(b) for b in data["bars"])

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


@dataclass(frozen=True)
class SceneObject:
    shape: str
    x: float
    y: float
    theta: float

    @property
    def pose(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.theta)


@dataclass
class Scene:
    """Objects on a table. ``group`` optionally names the objects to grasp (row scenes)."""

    objects: list[SceneObject]
    library: ShapeLibrary = field(default_factory=default_library, repr=False)
    table: tuple[float, float, float, float] = DEFAULT_TABLE
    group: tuple[int, ...] | None = None
    meta: dict = field(default_factory=dict)
    shapes_file: str | None = None

    def __len__(self) -> int:
        return len(self.objects)

    def shape(self, i: int) -> Shape:
        return self.library[self.objects[i].shape]

    def polygon(self, i: int) -> np.ndarray:
        o = self.objects[i]
        return transform(self.library[o.shape].vertices, o.x, o.y, o.theta)

    def polygons(self) -> PolygonSet:
        """The objects as arrays for the vectorized geometry (see PolygonSet)."""
        polys = [self.polygon(i) for i in range(len(self))]
        K = max((len(p) for p in polys), default=3)
        V = np.zeros((len(polys), K, 2))
        for i, p in enumerate(polys):
            V[i, : len(p)] = p
            V[i, len(p) :] = p[-1]
        return PolygonSet(
            vertices=V,
            counts=np.array([len(p) for p in polys], dtype=int),
            centers=np.array([[o.x, o.y] for o in self.objects]).reshape(-1, 2),
            radii=np.array([self.shape(i).radius for i in range(len(self))]),
            d_fmin=np.array([self.shape(i).d_fmin for i in range(len(self))]),
        )

    def shapely_polygons(self) -> np.ndarray:
        out = np.empty(len(self), dtype=object)
        out[:] = [shapely.Polygon(self.polygon(i)) for i in range(len(self))]
        return out

    def validate(self, overlap_tol: float = DEFAULT_OVERLAP_TOL) -> Scene:
        """Refuses unknown shapes, non-finite poses, objects off the table and overlaps."""
        x0, x1, y0, y1 = self.table
        if not all(math.isfinite(v) for v in self.table) or x1 <= x0 or y1 <= y0:
            raise MogError(f"table bounds must be finite with xmin < xmax and ymin < ymax, got {self.table}")
        for i, o in enumerate(self.objects):
            self.library[o.shape]  # raises on unknown shape
            if not all(math.isfinite(v) for v in o.pose):
                raise MogError(f"object {i} ({o.shape}): pose {list(o.pose)} is not finite")
        if self.group is not None:
            for g in self.group:
                if not 0 <= g < len(self):
                    raise MogError(f"group names object {g}, but the scene has {len(self)} objects")
        polys = self.shapely_polygons()
        table = shapely.box(x0, y0, x1, y1)
        for i, p in enumerate(polys):
            if shapely.area(shapely.difference(p, table)) > overlap_tol:
                raise MogError(f"object {i} ({self.objects[i].shape}) lies off the table {list(self.table)}")
        tree = shapely.STRtree(polys)
        a, b = tree.query(polys, predicate="intersects")
        for i, j in zip(a, b):
            if i < j and shapely.area(shapely.intersection(polys[i], polys[j])) > overlap_tol:
                raise MogError(
                    f"objects {i} ({self.objects[i].shape}) and {j} ({self.objects[j].shape}) overlap"
                )
        return self

    # --- YAML ---------------------------------------------------------------------------
    def to_dict(self) -> dict:
        d: dict = {}
        if self.shapes_file:
            d["shapes"] = self.shapes_file
        d["table"] = [float(v) for v in self.table]
        d["objects"] = [
            {"shape": o.shape, "pose": [round(float(v), 9) for v in o.pose]} for o in self.objects
        ]
        if self.group is not None:
            d["group"] = [int(g) for g in self.group]
        if self.meta:
            d["meta"] = self.meta
        return d

    def save(self, path: str | Path) -> None:
        Path(path).write_text(yaml.safe_dump(self.to_dict(), sort_keys=False, default_flow_style=None))

    @classmethod
    def from_dict(
        cls,
        data: dict,
        library: ShapeLibrary | None = None,
        where: str = "scene",
        base_dir: Path | None = None,
    ) -> Scene:
        unknown = set(data) - {"shapes", "table", "objects", "group", "meta"}
        if unknown:
            raise MogError(f"{where}: unknown key(s) {sorted(unknown)}")
        shapes_file = data.get("shapes")
        if library is None:
            if shapes_file:
                p = Path(shapes_file)
                if not p.is_absolute() and base_dir is not None:
                    p = base_dir / p
                library = ShapeLibrary.load(p)
            else:
                library = default_library()
        objs_raw = data.get("objects")
        if not isinstance(objs_raw, list):
            raise MogError(f"{where}: 'objects' must be a list")
        objects = []
        for i, o in enumerate(objs_raw):
            if not isinstance(o, dict) or "shape" not in o or "pose" not in o:
                raise MogError(f"{where}: object {i} needs 'shape' and 'pose: [x, y, theta]'")
            pose = o["pose"]
            try:
                x, y, th = (float(v) for v in pose)
            except (TypeError, ValueError):
                raise MogError(f"{where}: object {i} pose must be three numbers [x, y, theta]") from None
            objects.append(SceneObject(str(o["shape"]), x, y, th))
        table = data.get("table", DEFAULT_TABLE)
        try:
            table = tuple(float(v) for v in table)
            assert len(table) == 4
        except (TypeError, ValueError, AssertionError):
            raise MogError(f"{where}: 'table' must be [xmin, xmax, ymin, ymax]") from None
        group = data.get("group")
        if group is not None:
            try:
                group = tuple(int(g) for g in group)
            except (TypeError, ValueError):
                raise MogError(f"{where}: 'group' must be a list of object indices") from None
        scene = cls(objects, library, table, group, dict(data.get("meta", {}) or {}), shapes_file)
        try:
            return scene.validate()
        except MogError as e:
            raise MogError(f"{where}: {e}") from None

    @classmethod
    def load(cls, path: str | Path, library: ShapeLibrary | None = None) -> Scene:
        path = Path(path)
        return cls.from_dict(_read_yaml(path), library, where=str(path), base_dir=path.parent)


# --- generators -------------------------------------------------------------------------

#: The paper's row classes 2..7 (Sec. 7.2); "irregular" draws a non-bar shape. Class 1, a
#: single irregular object, is ours (benchmarks and single-object checks).
ROW_CLASSES: dict[int, tuple[str, ...]] = {
    1: ("irregular",),
    2: ("irregular", "irregular"),
    3: ("irregular", "thin_bar", "thick_bar"),
    4: ("irregular", "thin_bar", "thin_bar", "thick_bar"),
    5: ("irregular", "thin_bar", "thin_bar", "thick_bar", "thick_bar"),
    6: ("thin_bar",) * 4 + ("thick_bar",) * 2,
    7: ("thin_bar",) * 7,
}


@dataclass(frozen=True)
class RowParams:
    """Jitter of the paper's row scenes: objects in a tight row along the closing axis (x)."""

    gap: float = 0.001  # minimum distance between neighbours (m)
    yaw_jitter: float = math.radians(18.0)  # +- around the minimum-width-along-x orientation
    lateral_jitter: float = 0.015  # +- in y (m)


def row_scene(
    n_class: int,
    rng: np.random.Generator,
    library: ShapeLibrary | None = None,
    params: RowParams = RowParams(),
) -> Scene:
    """A scene of the paper's class ``n_class`` (2..7, or 1): the objects of the class mix in random
    order, in a row along x with ``params.gap`` between neighbours. Each object is turned so
    that its minimum width lies along x (flipped by pi at random), plus uniform yaw jitter,
    and shifted in y by uniform lateral jitter. The whole row is the group."""
    library = library or default_library()
    if n_class not in ROW_CLASSES:
        raise MogError(f"row class must be one of {sorted(ROW_CLASSES)}, got {n_class}")
    names = [
        library.irregular[rng.integers(len(library.irregular))] if k == "irregular" else k
        for k in ROW_CLASSES[n_class]
    ]
    names = [names[i] for i in rng.permutation(len(names))]
    objects: list[SceneObject] = []
    placed = None
    for name in names:
        shape = library[name]
        n = shape.min_width_normal
        yaw = -math.atan2(n[1], n[0]) + (math.pi if rng.random() < 0.5 else 0.0)
        yaw += rng.uniform(-params.yaw_jitter, params.yaw_jitter)
        yaw = math.remainder(yaw, 2 * math.pi)
        y = rng.uniform(-params.lateral_jitter, params.lateral_jitter)
        body = transform(shape.vertices, 0.0, y, yaw)
        x = 0.0 if placed is None else _slide_into_row(placed, body, objects[-1].x, params.gap)
        objects.append(SceneObject(name, x, y, yaw))
        poly = shapely.Polygon(body + [x, 0.0])
        placed = poly if placed is None else shapely.union(placed, poly)
    xmin, _, xmax, _ = placed.bounds
    shift = -(xmin + xmax) / 2
    objects = [SceneObject(o.shape, o.x + shift, o.y, o.theta) for o in objects]
    scene = Scene(objects, library, group=tuple(range(len(objects))), meta={"kind": "row", "class": n_class})
    return scene.validate()


def _slide_into_row(placed, body: np.ndarray, last_x: float, gap: float) -> float:
    """x at which ``body`` (vertices at x = 0) stands right of ``placed`` at distance ``gap``:
    start clear of the row, slide left until the gap is reached (but not past the previous
    object's centre), then refine by bisection."""
    x = placed.bounds[2] + gap - body[:, 0].min()
    step = 0.0005
    while x - step > last_x:
        d = shapely.distance(placed, shapely.Polygon(body + [x - step, 0.0]))
        if d < gap:
            lo, hi = x - step, x
            for _ in range(30):
                mid = 0.5 * (lo + hi)
                if shapely.distance(placed, shapely.Polygon(body + [mid, 0.0])) < gap:
                    lo = mid
                else:
                    hi = mid
            return hi
        x -= step
    return x


@dataclass(frozen=True)
class ClutterParams:
    """Objects dropped in a few clusters inside ``region`` (xmin, xmax, ymin, ymax)."""

    region: tuple[float, float, float, float] = (-0.15, 0.15, -0.15, 0.15)
    n_clusters: int = 4
    spread: float = 0.03  # standard deviation of positions around a cluster centre (m)
    gap: float = 0.001  # minimum distance between objects (m)


def cluttered_scene(
    rng: np.random.Generator,
    library: ShapeLibrary | None = None,
    inventory: str = "isrr33",
    n_objects: int | None = None,
    params: ClutterParams = ClutterParams(),
) -> Scene:
    """A cluttered table like the paper's physical scenes: the inventory's objects (or the first
    ``n_objects`` of it after shuffling) dropped around ``n_clusters`` random centres with random
    yaw, without overlap and inside the region. Deterministic given ``rng``."""
    library = library or default_library()
    names = library.inventory(inventory)
    names = [names[i] for i in rng.permutation(len(names))]
    if n_objects is not None:
        if not 1 <= n_objects <= len(names):
            raise MogError(
                f"n_objects must be in 1..{len(names)} for inventory '{inventory}', got {n_objects}"
            )
        names = names[:n_objects]
    x0, x1, y0, y1 = params.region
    margin = 0.03
    if x1 - x0 <= 2 * margin or y1 - y0 <= 2 * margin:
        raise MogError(f"clutter region {list(params.region)} is too small")
    centres = np.column_stack(
        [
            rng.uniform(x0 + margin, x1 - margin, params.n_clusters),
            rng.uniform(y0 + margin, y1 - margin, params.n_clusters),
        ]
    )
    region = shapely.box(x0, y0, x1, y1)
    placed: list = []
    objects: list[SceneObject] = []
    for k, name in enumerate(names):
        shape = library[name]
        c = centres[k % params.n_clusters]
        spread = params.spread
        for attempt in range(2000):
            if attempt and attempt % 200 == 0:
                spread *= 1.5
            x, y = rng.normal(c, spread)
            th = rng.uniform(-math.pi, math.pi)
            poly = shapely.Polygon(transform(shape.vertices, x, y, th))
            if not region.contains(poly):
                continue
            if placed and shapely.distance(poly, np.array(placed, dtype=object)).min() < params.gap:
                continue
            placed.append(poly)
            objects.append(SceneObject(name, float(x), float(y), float(th)))
            break
        else:
            raise MogError(f"could not place object {k} ({name}) without overlap: region too small")
    scene = Scene(objects, library, meta={"kind": "cluttered", "inventory": inventory})
    return scene.validate()
