"""PNG figures of the experiments, laid out like the paper's."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from mog_drake.files import atomic_path

# The paper's figures (REFERENCE Sec. 3), drawn beside ours.
PAPER_TN_BY_CLASS = {"2": 96.0, "3": 85.5, "4": 96.3, "5": 93.3, "6": 93.9, "7": 95.2}


def conditions_figure(summary: dict, path: str | Path) -> Path:
    rows = [r for r in summary["rows"] if r["class"] != "all"]
    labels = [r["class"] for r in rows]
    x = np.arange(len(rows))
    fig, ax = plt.subplots(figsize=(7, 4))
    w = 0.2
    ax.bar(x - 1.5 * w, [r["tn_area_pct"] for r in rows], w, label="int. area", color="#c0392b")
    ax.bar(x - 0.5 * w, [r["tn_diameter_pct"] for r in rows], w, label="diameter", color="#e67e22")
    ax.bar(x + 0.5 * w, [r["tn_either_pct"] for r in rows], w, label="both conditions", color="#27ae60")
    ax.bar(
        x + 1.5 * w, [PAPER_TN_BY_CLASS.get(c, np.nan) for c in labels], w, label="paper (both)", color="0.6"
    )
    ax.set_xticks(x, [f"{c} obj" for c in labels])
    ax.set_ylabel("true negatives predicted (%)")
    ax.set_ylim(0, 105)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title("Necessary conditions vs physics ground truth", fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    return _save(fig, path)


def planner_figure(summary: dict, path: str | Path) -> Path:
    rows = [r for r in summary["rows"] if r["class"] != "all"]
    classes = sorted({r["class"] for r in rows}, key=int)
    methods = list(dict.fromkeys(r["method"] for r in rows))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    w = 0.8 / max(len(methods), 1)
    for j, m in enumerate(methods):
        rs = [next(r for r in rows if r["class"] == c and r["method"] == m) for c in classes]
        x = np.arange(len(classes)) + (j - (len(methods) - 1) / 2) * w
        axes[0].bar(
            x,
            [r["time_s"] for r in rs],
            w,
            yerr=[np.nan_to_num(r["time_ci"]) for r in rs],
            label=m,
            capsize=2,
        )
        axes[1].bar(
            x,
            [r["tested"] for r in rs],
            w,
            yerr=[np.nan_to_num(r["tested_ci"]) for r in rs],
            label=m,
            capsize=2,
        )
    for ax, ylabel in zip(axes, ("planning time (s)", "candidates tested in physics")):
        ax.set_xticks(np.arange(len(classes)), [f"{c} obj" for c in classes])
        ax.set_ylabel(ylabel)
        ax.set_yscale("log")
        ax.grid(axis="y", alpha=0.3)
    axes[1].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[0].set_title("Planning time (95 % CI)", fontsize=10)
    axes[1].set_title("Physics checks (95 % CI)", fontsize=10)
    return _save(fig, path)


def _save(fig, path) -> Path:
    path = Path(path)
    fig.tight_layout()
    with atomic_path(path) as tmp:  # a killed write leaves the earlier figure whole
        fig.savefig(tmp, dpi=130)
    plt.close(fig)
    return path


def picking_figure(summary: dict, path: str | Path, paper: dict | None = None) -> Path:
    """``paper``: {mode: {success_rate, picked_pct, pph}}, the paper's bars beside ours."""
    paper = paper or {}
    rows = summary["rows"]
    beside = any(r["mode"] in paper for r in rows)  # no paper bars: ours alone, centred
    shift, width = (0.2, 0.4) if beside else (0.0, 0.5)
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.5))
    for ax, key, label in zip(
        axes,
        ("success_rate", "picked_pct", "pph"),
        ("grasp success (%)", "objects picked (%)", "picks per hour"),
    ):
        x = np.arange(len(rows))
        ax.bar(
            x - shift,
            [r[key] for r in rows],
            width,
            yerr=[np.nan_to_num(r[key + "_ci"]) for r in rows],
            capsize=3,
            label="ours (sim)",
        )
        if beside:
            ax.bar(
                x + shift,
                [paper.get(r["mode"], {}).get(key, np.nan) for r in rows],
                width,
                color="0.6",
                label="paper (real UR5)",
            )
        ax.set_xticks(x, [r["mode"] for r in rows])
        ax.set_xlim(-0.8, len(rows) - 0.2)  # one mode's bar as wide as three modes' would be
        ax.set_title(label, fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    axes[-1].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return _save(fig, path)


MODE_COLORS = {"mog": "#2471a3", "sog": "#c0392b", "push-mog": "#1e8449"}


def study_figure(rows: list[dict], path: str | Path, title: str = "", paper: dict | None = None) -> Path:
    """The uncertainty study: success and objects per successful grasp against the level of
    uncertainty, per mode (95 % intervals). ``rows``: one per level and mode (`frames.study`'s
    records), with ``level``; ``paper``: {mode: {success_rate, objects_per_success}}, the
    paper's real robot marked."""
    paper = paper or {}
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    modes = list(dict.fromkeys(r["mode"] for r in rows))
    for m in modes:
        rs = sorted((r for r in rows if r["mode"] == m), key=lambda r: r["level"])
        lv = [r["level"] for r in rs]
        c = MODE_COLORS.get(m)
        for ax, key in zip(axes, ("success_rate", "objects_per_success")):
            ax.errorbar(
                lv, [r[key] for r in rs], yerr=[np.nan_to_num(r[key + "_ci"]) for r in rs],
                marker="o", capsize=3, color=c, label=f"{m}, simulated",
            )  # fmt: skip
        if m in paper:
            for ax, key in zip(axes, ("success_rate", "objects_per_success")):
                ax.axhline(paper[m][key], color=c, ls="--", lw=1, label=f"{m}, the paper's UR5")
    axes[0].set_ylabel("successful grasps (%)")
    axes[1].set_ylabel("objects per successful grasp")
    # A level run on few tables has an interval wider than the scale; the scale stays the
    # measure's own (intervals drawn past it are cut at the frame).
    axes[0].set_ylim(0, 105)
    axes[1].set_ylim(0.9, 2.1)
    for ax in axes:
        ax.set_xlabel("uncertainty level (x the level-1 magnitudes)")
        ax.set_xticks(sorted({r["level"] for r in rows}))  # the levels run, not fractions of one
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0))  # clear of the data
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, path)
