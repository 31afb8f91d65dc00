"""Pictures of scenes, groups and grasp candidates (matplotlib), shared by the CLI and notebooks."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import shapely
from matplotlib.collections import LineCollection
from matplotlib.patches import Polygon as MplPolygon

from mog_drake.files import atomic_path
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
    *,
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
        ax.legend(
            loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, title="candidates", title_fontsize=7
        )
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


def scene_picture(
    scene, group, output, candidates: bool = False, positions: int = 70, orientations: int = 7, **figure
) -> Path:
    """`scene_figure` written to ``output``; with ``candidates`` every candidate of ``group``
    coloured by verdict (its grid: ``positions`` by ``orientations``)."""
    from mog_drake.geometry import ranked_candidates

    gripper = figure.pop("gripper", None) or GripperGeometry()
    ev = order = None
    if candidates:
        ev, order = ranked_candidates(scene.polygons(), group, gripper, positions, orientations)
    return save(scene_figure(scene, group, ev, order, gripper=gripper, **figure), output)


def save(fig, path: str | Path) -> Path:
    path = Path(path)
    with atomic_path(path) as tmp:  # a killed write leaves the earlier figure whole
        fig.savefig(tmp, dpi=130)
    plt.close(fig)
    return path


def groups_figure(scene, groups, title: str | None = None):
    """The scene with the convex hull of each object group outlined in its own colour."""
    fig, ax = plt.subplots(figsize=(7, 6))
    draw_scene(ax, scene, alpha=0.6)
    cmap = plt.get_cmap("tab10")
    for k, g in enumerate(groups):
        if len(g) < 2:
            continue
        hull = shapely.convex_hull(shapely.MultiPoint(np.concatenate([scene.polygon(int(i)) for i in g])))
        xy = np.asarray(hull.exterior.coords) * 1000
        ax.plot(xy[:, 0], xy[:, 1], color=cmap(k % 10), lw=2, label=f"{list(g)}")
    pts = np.concatenate([scene.polygon(i) for i in range(len(scene))]) * 1000
    ax.set_xlim(pts[:, 0].min() - 20, pts[:, 0].max() + 20)
    ax.set_ylim(pts[:, 1].min() - 20, pts[:, 1].max() + 20)
    ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.0, 1.0), title="groups")
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return fig


def ranking_figure(ev: GraspEvaluation, order, top: int = 40):
    """Total intersection area A_T of the ``top`` best-ranked collision-free candidates (the
    ones GraspPlanner ranks), coloured by the condition they fail or pass."""
    order = [int(i) for i in order if ev.collision_free[int(i)]][:top]
    fig, ax = plt.subplots(figsize=(9, 3))
    verdicts = [ev.verdict(i) for i in order]
    ax.bar(np.arange(len(order)), ev.area_total[order] * 1e6, color=[VERDICT_COLORS[v] for v in verdicts])
    for verdict in dict.fromkeys(verdicts):
        ax.bar([0], [0], color=VERDICT_COLORS[verdict], label=verdict)
    ax.set_xlabel("rank among the collision-free candidates")
    ax.set_ylabel("A_T (mm^2)")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title("RankGraspCands: collision-free candidates by total intersection area", fontsize=10)
    fig.tight_layout()
    return fig


def candidate_table(ev: GraspEvaluation, order, limit: int = 20):
    """Per-candidate figures (mm, mm^2, deg): a pandas DataFrame if pandas is installed, else a list of dicts."""
    rows = []
    for rank, i in enumerate(np.asarray(order)[:limit]):
        i = int(i)
        row = {
            "rank": rank,
            "x_mm": ev.grasps[i, 0] * 1e3,
            "y_mm": ev.grasps[i, 1] * 1e3,
            "theta_deg": np.degrees(ev.grasps[i, 2]),
            "h0_mm": ev.h0[i] * 1e3,
            "h_fmin_mm": ev.h_fmin * 1e3,
        }
        row.update({f"A_{g}_mm2": a * 1e6 for g, a in zip(ev.group, ev.areas[i])})
        row["A_T_mm2"] = ev.area_total[i] * 1e6
        row["verdict"] = ev.verdict(i)
        rows.append(row)
    try:
        import pandas as pd
    except ImportError:
        return rows
    return pd.DataFrame(rows).set_index("rank")


def write_diagram(diagram, out: str | Path) -> Path:
    """A Diagram's top-level wiring to ``out``: Graphviz source (.dot), drawn by graphviz if
    it is installed, else by matplotlib."""
    import shutil
    import subprocess

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    dot = diagram.GetGraphvizString(max_depth=1)
    if out.suffix == ".dot":
        out.write_text(dot)
    elif shutil.which("dot"):
        subprocess.run(
            ["dot", f"-T{out.suffix[1:] or 'svg'}", "-o", str(out)], input=dot.encode(), check=True
        )
    else:
        save(diagram_figure(diagram), out)
    return out


def diagram_figure(diagram, title: str | None = None):
    """The top-level wiring of a Drake Diagram: one box per subsystem, one arrow per connection
    labelled with the port names (no graphviz needed)."""
    systems = list(diagram.GetSystems())
    names = [s.get_name() for s in systems]
    n = len(systems)
    ang = np.linspace(np.pi / 2, np.pi / 2 - 2 * np.pi, n, endpoint=False)
    pos = {name: (3.2 * np.cos(a), 2.2 * np.sin(a)) for name, a in zip(names, ang)}
    fig, ax = plt.subplots(figsize=(10, 7))
    for name, (x, y) in pos.items():
        ax.text(
            x,
            y,
            name,
            ha="center",
            va="center",
            fontsize=10,
            bbox={"boxstyle": "round,pad=0.5", "fc": "#e8f1fb", "ec": "#1f77b4"},
        )
    pairs: dict = {}
    for (out_sys, out_port), (in_sys, in_port) in _connections(diagram):
        label = out_port if out_port == in_port else f"{out_port} -> {in_port}"
        pairs.setdefault((out_sys, in_sys), []).append(label)
    for (out_sys, in_sys), labels in pairs.items():
        (x0, y0), (x1, y1) = pos[out_sys], pos[in_sys]
        ax.annotate(
            "",
            xy=(x1, y1),
            xytext=(x0, y0),
            arrowprops={
                "arrowstyle": "->",
                "color": "0.4",
                "shrinkA": 28,
                "shrinkB": 28,
                "connectionstyle": "arc3,rad=0.15",
            },
        )
        # Label on the arrow's side of the chord (arcs bend to the right of travel).
        dx, dy = x1 - x0, y1 - y0
        norm = max(np.hypot(dx, dy), 1e-9)
        mx, my = (x0 + x1) / 2 + 0.35 * dy / norm, (y0 + y1) / 2 - 0.35 * dx / norm
        ax.text(
            mx,
            my,
            "\n".join(sorted(labels)),
            fontsize=7,
            color="0.2",
            ha="center",
            va="center",
            bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.8},
        )
    ax.set_xlim(-4.5, 4.5)
    ax.set_ylim(-3.0, 3.0)
    ax.axis("off")
    ax.set_title(title or diagram.get_name(), fontsize=11)
    fig.tight_layout()
    return fig


def _connections(diagram):
    """((source system, output port), (destination system, input port)) name pairs."""
    out = []
    for (dst_sys, dst_idx), (src_sys, src_idx) in diagram.connection_map().items():
        out.append(
            (
                (src_sys.get_name(), src_sys.get_output_port(src_idx).get_name()),
                (dst_sys.get_name(), dst_sys.get_input_port(dst_idx).get_name()),
            )
        )
    return out
