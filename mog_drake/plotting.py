"""Pictures of scenes, groups and grasp candidates (matplotlib), shared by the CLI and notebooks."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import shapely
from matplotlib.collections import LineCollection
from matplotlib.patches import Polygon as MplPolygon

from mog_drake.geometry.conditions import GraspEvaluation
from mog_drake.geometry.gripper import GripperGeometry

VERDICT_COLORS = {"collision": "#9e9e9e", "diameter": "#e67e22", "area": "#c0392b", "passed": "#27ae60"}


def draw_scene(ax, scene, group=None, label: bool = True, alpha: float = 0.9) -> None:
    """Draws every object in its library colour; group members get a thick black outline."""
    group = set(group or ())
    for i in range(len(scene)):
        p = scene.polygon(i)
        shape = scene.shape(i)
        ax.add_patch(
            MplPolygon(
                p * 1000,
                closed=True,
                facecolor=shape.color[:3],
                alpha=alpha,
                edgecolor="black" if i in group else "0.35",
                linewidth=2.0 if i in group else 0.6,
            )
        )
        if label:
            c = p.mean(axis=0) * 1000
            ax.text(c[0], c[1], str(i), ha="center", va="center", fontsize=7, color="black")
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")


def draw_gripper(ax, grasp, gripper: GripperGeometry, color="black", s_alpha=0.12, lw=1.2) -> None:
    """The two jaws (filled) and the inner region S (outlined) of one grasp."""
    rects = gripper.rectangles(grasp)
    for name in ("left_jaw", "right_jaw"):
        ax.add_patch(
            MplPolygon(rects[name] * 1000, closed=True, facecolor=color, alpha=0.85, edgecolor=color)
        )
    ax.add_patch(
        MplPolygon(
            rects["S"] * 1000, closed=True, facecolor=color, alpha=s_alpha, edgecolor=color, lw=lw, ls="--"
        )
    )


def draw_intersections(ax, scene, grasp, group, gripper: GripperGeometry, color="#c0392b") -> None:
    """The intersection polygons o_i^s = S ∩ O_i of a grasp, hatched."""
    S = shapely.Polygon(gripper.rectangles(grasp)["S"])
    for i in group:
        inter = shapely.intersection(S, shapely.Polygon(scene.polygon(int(i))))
        if not inter.is_empty and inter.area > 0 and inter.geom_type == "Polygon":
            ax.add_patch(
                MplPolygon(
                    np.asarray(inter.exterior.coords) * 1000,
                    closed=True,
                    facecolor=color,
                    alpha=0.55,
                    edgecolor=color,
                    hatch="//",
                )
            )


def draw_candidates(ax, ev: GraspEvaluation, gripper: GripperGeometry, length: float = 0.006) -> None:
    """Each candidate as a short tick along its closing axis, coloured by verdict."""
    for verdict, color in VERDICT_COLORS.items():
        idx = [i for i in range(len(ev)) if ev.verdict(i) == verdict]
        if not idx:
            continue
        g = ev.grasps[idx]
        d = np.stack([np.cos(g[:, 2]), np.sin(g[:, 2])], axis=1) * length / 2
        segs = np.stack([g[:, :2] - d, g[:, :2] + d], axis=1) * 1000
        ax.add_collection(
            LineCollection(segs, colors=color, linewidths=1.0, alpha=0.8, label=f"{verdict} ({len(idx)})")
        )


def scene_figure(
    scene,
    group=None,
    ev: GraspEvaluation | None = None,
    order=None,
    top: int = 3,
    gripper: GripperGeometry | None = None,
    title: str | None = None,
    grasp=None,
):
    """A figure of the scene; with ``ev`` the candidates coloured by verdict and the S region
    and intersection polygons of the ``top`` best-ranked candidates that pass both conditions;
    with ``grasp`` that one grasp drawn with its intersections."""
    gripper = gripper or GripperGeometry()
    fig, ax = plt.subplots(figsize=(7, 6))
    draw_scene(ax, scene, group)
    if ev is not None:
        draw_candidates(ax, ev, gripper)
        order = np.arange(len(ev)) if order is None else np.asarray(order)
        passed = [int(i) for i in order if ev.passed[i]][:top]
        for rank, i in enumerate(passed):
            draw_gripper(ax, ev.grasps[i], gripper, color=["#1f77b4", "#9467bd", "#17becf"][rank % 3])
            draw_intersections(ax, scene, ev.grasps[i], ev.group, gripper)
        ax.legend(loc="upper right", fontsize=7, title="candidates", title_fontsize=7)
    if grasp is not None:
        draw_gripper(ax, grasp, gripper, color="#1f77b4")
        draw_intersections(ax, scene, grasp, group if group is not None else range(len(scene)), gripper)
    pts = (
        np.concatenate([scene.polygon(i) for i in range(len(scene))]) * 1000
        if len(scene)
        else np.zeros((1, 2))
    )
    pad = 50.0
    ax.set_xlim(pts[:, 0].min() - pad, pts[:, 0].max() + pad)
    ax.set_ylim(pts[:, 1].min() - pad, pts[:, 1].max() + pad)
    ax.grid(alpha=0.25)
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return fig


def save(fig, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path
