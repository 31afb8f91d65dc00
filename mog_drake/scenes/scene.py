"""A scene: objects (library shape, pose x, y, theta) on a table, its checks and YAML I/O."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import shapely
import yaml

from mog_drake.errors import MogError
from mog_drake.geometry.conditions import PolygonSet
from mog_drake.geometry.polygon import (
    transform,
)
from mog_drake.scenes.library import Shape, ShapeLibrary, default_library, read_yaml

#: Default table top (xmin, xmax, ymin, ymax) in m: objects must lie inside it.
DEFAULT_TABLE = (-0.25, 0.25, -0.25, 0.25)
#: Table bounds (m) beyond this are typos; so is a yaw beyond MAX_YAW (rad).
MAX_TABLE = 100.0
MAX_YAW = 1e3
#: Two objects may overlap by at most this area (m^2, = 1 mm^2) before a scene is refused.
DEFAULT_OVERLAP_TOL = 1e-6
#: Objects in one scene at most: several times what a tabletop holds, few enough that the
#: pairwise overlap check stays within seconds.
MAX_OBJECTS = 500


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

    def chosen_group(self, given=None) -> tuple[tuple[int, ...], str]:
        """The group to grasp and where it came from: ``given`` (--group) if any, checked
        against the scene, else `default_group` for the default gripper."""
        if not given:
            from mog_drake.geometry import GripperGeometry

            return self.default_group(GripperGeometry().w_g)
        for g in given:
            if not 0 <= g < len(self):
                raise MogError(
                    f"--group names object {g}, but the scene has {len(self)} objects (0..{len(self) - 1})"
                )
        if len(set(given)) != len(given):
            raise MogError("--group names an object twice")
        return tuple(given), "argument"

    def default_group(self, w_g: float) -> tuple[tuple[int, ...], str]:
        """(group, where it came from): the scene's own group ("scene"), else Alg. 1's first
        group for a gripper of stroke ``w_g`` ("largest")."""
        from mog_drake.geometry import create_obj_groups, rank_obj_groups

        if self.group is not None:
            return tuple(self.group), "scene"
        polys = self.polygons()
        ranked = rank_obj_groups(create_obj_groups(polys.centers), polys.d_fmin, w_g)
        if not ranked:
            raise MogError("the scene has no graspable group; pass --group")
        return ranked[0], "largest"

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
        if not all(math.isfinite(v) and abs(v) <= MAX_TABLE for v in self.table) or x1 <= x0 or y1 <= y0:
            raise MogError(
                f"table bounds must be within +-{MAX_TABLE:g} m with xmin < xmax and ymin < ymax, got {list(self.table)}"
            )
        for i, o in enumerate(self.objects):
            self.library[o.shape]  # raises on unknown shape
            if not all(math.isfinite(v) for v in o.pose):
                raise MogError(f"object {i} ({o.shape}): pose {list(o.pose)} is not finite")
            # Checked on the numbers first: far enough out, a polygon collapses in floating
            # point and its area no longer says where it is.
            if not (x0 <= o.x <= x1 and y0 <= o.y <= y1):
                raise MogError(
                    f"object {i} ({o.shape}) at ({o.x:g}, {o.y:g}) lies off the table {list(self.table)}"
                )
            if abs(o.theta) > MAX_YAW:
                raise MogError(
                    f"object {i} ({o.shape}): yaw {o.theta:g} rad is not an angle (|theta| <= {MAX_YAW:g})"
                )
        if self.group is not None:
            if not self.group:
                raise MogError("group is empty: name at least one object, or leave 'group' out")
            for g in self.group:
                if not 0 <= g < len(self):
                    raise MogError(f"group names object {g}, but the scene has {len(self)} objects")
            if len(set(self.group)) != len(self.group):
                raise MogError(f"group {list(self.group)} names an object twice")
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

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False, default_flow_style=None)

    def save(self, path: str | Path) -> None:
        Path(path).write_text(self.to_yaml())

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
        if shapes_file is not None and not isinstance(shapes_file, str):
            raise MogError(f"{where}: 'shapes' must be the path of a shapes file, got {shapes_file!r}")
        if library is None:
            if shapes_file:
                p = Path(shapes_file)
                if not p.is_absolute() and base_dir is not None:
                    p = base_dir / p
                library = ShapeLibrary.load(p)
            else:
                library = default_library()
        meta = data.get("meta") or {}
        if not isinstance(meta, dict):
            raise MogError(f"{where}: 'meta' must be a mapping, got {type(meta).__name__}")
        objs_raw = data.get("objects")
        if not isinstance(objs_raw, list) or not objs_raw:
            raise MogError(f"{where}: 'objects' must be a list of at least one object")
        if len(objs_raw) > MAX_OBJECTS:
            raise MogError(f"{where}: {len(objs_raw)} objects; a table holds at most {MAX_OBJECTS}")
        objects = []
        for i, o in enumerate(objs_raw):
            if not isinstance(o, dict) or "shape" not in o or "pose" not in o:
                raise MogError(f"{where}: object {i} needs 'shape' and 'pose: [x, y, theta]'")
            pose = o["pose"]
            try:
                if isinstance(pose, (str, bytes, dict)) or any(isinstance(v, bool) for v in pose):
                    raise TypeError
                x, y, th = (float(v) for v in pose)
            except (TypeError, ValueError, OverflowError):
                raise MogError(f"{where}: object {i} pose must be three numbers [x, y, theta]") from None
            if not isinstance(o["shape"], str):
                raise MogError(f"{where}: object {i} shape must be a shape's name, got {o['shape']!r}")
            objects.append(SceneObject(o["shape"], x, y, th))
        table = data.get("table", DEFAULT_TABLE)
        try:
            if isinstance(table, (str, bytes, dict)):
                raise TypeError
            table = tuple(float(v) for v in table)
            assert len(table) == 4
        except (TypeError, ValueError, AssertionError, OverflowError):
            raise MogError(f"{where}: 'table' must be [xmin, xmax, ymin, ymax]") from None
        group = data.get("group")
        if group is not None:
            try:
                if isinstance(group, (str, bytes, dict)) or not all(
                    isinstance(g, int) and not isinstance(g, bool) for g in group
                ):
                    raise TypeError
                group = tuple(group)
            except (TypeError, ValueError):
                raise MogError(f"{where}: 'group' must be a list of object indices") from None
        scene = cls(objects, library, table, group, dict(meta), shapes_file)
        try:
            return scene.validate()
        except MogError as e:
            raise MogError(f"{where}: {e}") from None

    @classmethod
    def load(cls, path: str | Path, library: ShapeLibrary | None = None) -> Scene:
        path = Path(path)
        return cls.from_dict(read_yaml(path), library, where=str(path), base_dir=path.parent)


# --- generators -------------------------------------------------------------------------
