"""Seeded scene generators: the paper's row classes and cluttered tables."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from mog_drake.errors import MogError
from mog_drake.geometry.polygon import (
    transform,
)
from mog_drake.scenes.library import ShapeLibrary, default_library
from mog_drake.scenes.scene import Scene, SceneObject

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


def generate_scene(
    kind: str,
    seed: int,
    library: ShapeLibrary | None = None,
    row_class: int | None = None,
    n_objects: int | None = None,
    inventory: str = "isrr33",
    *,
    clusters: int = 4,
) -> Scene:
    """A seeded ``kind`` scene: "row" (class ``row_class``, Sec. 7.2) or "cluttered"
    (``n_objects`` of ``inventory`` in ``clusters`` clusters, Table 1), its seed in its meta."""
    rng = np.random.default_rng(seed)
    library = library or default_library()
    if kind == "row":
        if row_class is None:
            raise MogError("--kind row needs --class N (1..7)")
        scene = row_scene(row_class, rng, library)
    else:
        scene = cluttered_scene(
            rng, library, inventory=inventory, n_objects=n_objects, params=ClutterParams(n_clusters=clusters)
        )
    scene.meta["seed"] = seed
    return scene
