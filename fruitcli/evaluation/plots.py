"""Plots like the paper's Figs. 12-14: truth as red squares, measurement as blue dots,
a black line joining each pair; axes in mm with equal aspect. Functions take an Axes."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes

PLOT_MAX_PAIRS = 5000
"""Pairs drawn at most; larger sets are shown by an evenly spaced subset."""


def pairs(
    ax: Axes,
    truth: np.ndarray,
    measured: np.ndarray,
    axes: tuple[int, int] = (0, 1),
    labels: tuple[str, str] = ("x", "y"),
    title: str = "",
) -> Axes:
    """Draw matched pairs projected on two coordinate `axes` (0=x, 1=y, 2=z)."""
    from matplotlib.collections import LineCollection

    a, b = axes
    if len(truth) > PLOT_MAX_PAIRS:  # evenly spaced pairs: a readable plot, drawn in seconds
        keep = np.linspace(0, len(truth) - 1, PLOT_MAX_PAIRS).astype(int)
        title = f"{title} ({PLOT_MAX_PAIRS} of {len(truth)} pairs)" if title else title
        truth, measured = truth[keep], measured[keep]
    segments = np.stack([truth[:, [a, b]], measured[:, [a, b]]], axis=1)
    ax.add_collection(LineCollection(list(segments), colors="black", linewidths=0.8, zorder=1))
    ax.scatter(
        truth[:, a], truth[:, b], marker="s", color="red", s=22, label="Ground truth", zorder=2
    )
    ax.scatter(
        measured[:, a],
        measured[:, b],
        marker="o",
        color="blue",
        s=18,
        label="Measurement",
        zorder=3,
    )
    ax.set_xlabel(f"{labels[0].upper()}-Position (mm)")
    ax.set_ylabel(f"{labels[1].upper()}-Position (mm)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, color="0.8")
    ax.legend(loc="best", fontsize=8)
    if title:
        ax.set_title(title)
    return ax


def save_pair_views(
    out_dir: Path, truth: np.ndarray, measured: np.ndarray, label: str
) -> list[str]:
    """Write top.png (x-y) and, for 3D data, side.png (y-z). Returns the file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fruitcli.fsutil import atomic_path

    names = []
    views = [("top.png", (0, 1), ("x", "y"), "Top view")]
    if truth.shape[1] == 3:
        views.append(("side.png", (1, 2), ("y", "z"), "Side view"))
    for name, axes, labels, what in views:
        fig, ax = plt.subplots(figsize=(6, 5) if name == "top.png" else (7, 3.6))
        pairs(ax, truth, measured, axes, labels, title=f"{label}: {what}")
        fig.tight_layout()
        with atomic_path(out_dir / name) as tmp:
            fig.savefig(tmp, dpi=110, format="png")
        plt.close(fig)
        names.append(name)
    return names
