"""Heat maps on the taxel grid (Figs. 9-11 analogues). Functions take an Axes, return it."""

from __future__ import annotations

import numpy as np


def grid_image(i: np.ndarray, j: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(I, J) image of per-taxel values at integer grid indices; NaN where no taxel."""
    img = np.full((int(i.max()) + 1, int(j.max()) + 1), np.nan)
    img[i, j] = values
    return img


def taxel_heatmap(ax, i: np.ndarray, j: np.ndarray, values: np.ndarray, title: str = "",
                  vmax: float | None = None, label: str = "counts", annotate: bool = True):
    """Per-taxel values as a heat map over the (i, j) grid, each cell labelled."""
    img = grid_image(i, j, values)
    im = ax.imshow(img, origin="lower", cmap="viridis", vmin=0.0,
                   vmax=vmax if vmax is not None else np.nanmax(img))
    ax.figure.colorbar(im, ax=ax, label=label)
    if annotate:
        for a, b, v in zip(i, j, values, strict=True):
            ax.text(b, a, f"{v:.1f}", ha="center", va="center", fontsize=6, color="w")
    ax.set_xlabel("taxel j")
    ax.set_ylabel("taxel i")
    ax.set_title(title)
    return ax


def save_heatmap(path, i, j, values, title, vmax=None, label="counts") -> None:
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
