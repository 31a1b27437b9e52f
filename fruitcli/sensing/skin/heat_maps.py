"""Heat maps of per-taxel values (Figs. 9-11 analogues): on the (i, j) grid, and on the
taxels' top-view positions over the body's outline. Functions take an Axes, return it."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes


def grid_image(i: np.ndarray, j: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(I, J) image of per-taxel values at integer grid indices; NaN where no taxel."""
    img = np.full((int(i.max()) + 1, int(j.max()) + 1), np.nan)
    img[i, j] = values
    return img


def taxel_heatmap(
    ax: Axes,
    i: np.ndarray,
    j: np.ndarray,
    values: np.ndarray,
    title: str = "",
    vmax: float | None = None,
    label: str = "counts",
    annotate: bool = True,
) -> Axes:
    """Per-taxel values as a heat map over the (i, j) grid, each cell labelled."""
    img = grid_image(i, j, values)
    im = ax.imshow(
        img,
        origin="lower",
        cmap="viridis",
        vmin=0.0,
        vmax=vmax if vmax is not None else np.nanmax(img),
    )
    ax.figure.colorbar(im, ax=ax, label=label)
    if annotate:
        for a, b, v in zip(i, j, values, strict=True):
            ax.text(b, a, f"{v:.1f}", ha="center", va="center", fontsize=6, color="w")
    ax.set_xlabel("taxel j")
    ax.set_ylabel("taxel i")
    ax.set_title(title)
    return ax


def save_heatmap(
    path: str | os.PathLike,
    i: np.ndarray,
    j: np.ndarray,
    values: np.ndarray,
    title: str,
    vmax: float | None = None,
    label: str = "counts",
) -> None:
    """Write one heat map PNG (matplotlib Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fruitcli.fsutil import atomic_path

    fig, ax = plt.subplots(figsize=(5, 6))
    taxel_heatmap(ax, i, j, values, title, vmax, label)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def taxel_topview(
    ax: Axes,
    xy_mm: np.ndarray,
    values: np.ndarray,
    outline_xy_mm: np.ndarray,
    title: str = "",
    vmax: float | None = None,
    label: str = "counts",
) -> Axes:
    """Per-taxel values as coloured discs at the taxels' top-view positions `xy_mm` (T, 2)
    over the body's outline: its surface triangles projected on x-y (F, 3, 2), in grey."""
    from matplotlib.collections import PolyCollection

    ax.add_collection(
        PolyCollection(list(outline_xy_mm), facecolors="0.88", edgecolors="none", zorder=0)
    )
    top = float(vmax if vmax is not None else np.max(values))
    sc = ax.scatter(
        xy_mm[:, 0],
        xy_mm[:, 1],
        c=values,
        cmap="viridis",
        vmin=0.0,
        vmax=top,
        s=230,
        edgecolors="0.3",
        linewidths=0.5,
        zorder=2,
    )
    ax.figure.colorbar(sc, ax=ax, label=label, shrink=0.85)
    for (x, y), v in zip(xy_mm, values, strict=True):
        ax.text(
            x,
            y,
            f"{v:.1f}",
            ha="center",
            va="center",
            fontsize=6,
            zorder=3,
            color="white" if v < 0.6 * top else "black",
        )
    lo, hi = outline_xy_mm.reshape(-1, 2).min(axis=0), outline_xy_mm.reshape(-1, 2).max(axis=0)
    pad = 0.04 * (hi - lo).max()
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(title, fontsize=10)
    return ax


def save_topview(
    path: str | os.PathLike,
    xy_mm: np.ndarray,
    values: np.ndarray,
    outline_xy_mm: np.ndarray,
    title: str,
    vmax: float | None = None,
    label: str = "counts",
) -> None:
    """Write one top-view heat map PNG (matplotlib Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fruitcli.fsutil import atomic_path

    span = np.ptp(outline_xy_mm.reshape(-1, 2), axis=0)
    width = 7.0
    fig, ax = plt.subplots(figsize=(width, max(3.5, width * span[1] / max(span[0], 1e-9))))
    taxel_topview(ax, xy_mm, values, outline_xy_mm, title, vmax, label)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
