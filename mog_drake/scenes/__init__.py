"""Object library, scenes, YAML I/O and seeded scene generators.

A scene is a list of objects (library shape, pose x, y, theta) lying on a table, in the table
frame (origin at the centre of the table top, z up). Units are SI.

* `library`: convex prism shapes (models/shapes.yaml) and their resting variants.
* `scene`: `Scene` and `SceneObject`, their checks and YAML I/O.
* `generators`: the paper's row classes (`row_scene`) and cluttered tables (`cluttered_scene`).
"""

from mog_drake.scenes.generators import ROW_CLASSES, ClutterParams, RowParams, cluttered_scene, row_scene
from mog_drake.scenes.library import (
    DEFAULT_SHAPES_FILE,
    Shape,
    ShapeLibrary,
    default_library,
    make_shape,
)
from mog_drake.scenes.scene import DEFAULT_OVERLAP_TOL, DEFAULT_TABLE, Scene, SceneObject

__all__ = [
    "DEFAULT_OVERLAP_TOL",
    "DEFAULT_SHAPES_FILE",
    "DEFAULT_TABLE",
    "ROW_CLASSES",
    "ClutterParams",
    "RowParams",
    "Scene",
    "SceneObject",
    "Shape",
    "ShapeLibrary",
    "cluttered_scene",
    "default_library",
    "make_shape",
    "row_scene",
]
