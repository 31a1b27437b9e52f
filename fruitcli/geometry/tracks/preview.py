"""preview.png: top view and perspective view of the tracked piece, taxels numbered."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes


def write_preview(
    path: str | Path,
    top_v: np.ndarray,
    top_f: np.ndarray,
    curves: list[np.ndarray],
    taxel_xyz: np.ndarray,
    title: str = "",
) -> None:
    """Save a two-panel PNG (mm axes) of the piece, its track curves and numbered taxels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(13, 6), dpi=110)
    ax = fig.add_subplot(1, 2, 1)
    t = top_v[top_f]
    facing_up = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])[:, 2] > 0
    ax.tripcolor(  # type: ignore[call-overload]  # stubs lack (x, y, triangles, c)
        top_v[:, 0],
        top_v[:, 1],
        top_f[facing_up],
        top_v[:, 2],
        cmap="Greys",
        shading="gouraud",
        alpha=0.8,
    )
    for c in curves:
        ax.plot(c[:, 0], c[:, 1], color="tab:orange", lw=0.8)
    ax.scatter(taxel_xyz[:, 0], taxel_xyz[:, 1], s=10, color="tab:red", zorder=3)
    _numbers(ax, taxel_xyz[:, :2], 6, 2)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title("top view")

    ax3 = fig.add_subplot(1, 2, 2)
    draw_perspective(ax3, top_v, top_f, curves, taxel_xyz)
    ax3.set_title("view from the front left, above (35 degrees)")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, bbox_inches="tight", pad_inches=0.15)  # tight_layout alone cut the x label
    plt.close(fig)


def _numbers(ax: Axes, xy: np.ndarray, fontsize: float, offset_pt: float) -> None:
    """Label point k of `xy` (k, 2) with k, `offset_pt` points up and right of it (plain
    texts on an offset transform: much cheaper to lay out than annotations)."""
    from matplotlib.transforms import offset_copy

    at = offset_copy(
        ax.transData, fig=ax.get_figure(root=True), x=offset_pt, y=offset_pt, units="points"
    )
    for k, p in enumerate(xy):
        ax.text(p[0], p[1], str(k), fontsize=fontsize, transform=at)


def view_matrix(elev_deg: float = 35.0, azim_deg: float = -60.0) -> np.ndarray:
    """Rows: screen x, screen y, depth (towards the viewer) for a camera at elevation
    `elev_deg` and azimuth `azim_deg` (matplotlib's 3D convention), orthographic."""
    e, a = np.radians(elev_deg), np.radians(azim_deg)
    toward = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    right = np.array([-np.sin(a), np.cos(a), 0.0])
    up = np.cross(toward, right)
    return np.stack([right, up, toward])


def draw_perspective(
    ax: Axes,
    v: np.ndarray,
    f: np.ndarray,
    curves: Sequence[np.ndarray],
    points: np.ndarray,
    elev_deg: float = 35.0,
    azim_deg: float = -60.0,
    flat: bool = False,
) -> Axes:
    """Shaded orthographic view of a mesh on a 2D Axes (Gouraud-shaded triangles in
    painter's order, far faces first: much faster than mplot3d), with curves and numbered
    points on it. `flat`: one shade per face (for boxy parts, whose long thin faces smear
    Gouraud shading)."""
    r = view_matrix(elev_deg, azim_deg)
    q = v @ r.T
    tri = q[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    vn = np.zeros_like(q)
    for k in range(3):
        np.add.at(vn, f[:, k], n)
    vn /= np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-12)
    front = f[n[:, 2] > 0]
    front = front[np.argsort(q[front, 2].mean(axis=1))]  # far faces first
    light = np.array([0.3, 0.5, 0.81])
    if flat:
        fn = np.cross(q[front[:, 1]] - q[front[:, 0]], q[front[:, 2]] - q[front[:, 0]])
        fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-12)
        shade = 0.25 + 0.75 * np.clip(fn @ light, 0, 1)
        ax.tripcolor(
            q[:, 0],
            q[:, 1],
            front,
            facecolors=shade,
            cmap="Greys_r",
            vmin=0.0,
            vmax=1.15,
            edgecolors="face",
            linewidth=0.1,
        )
    else:
        shade = 0.25 + 0.75 * np.clip(vn @ light, 0, 1)
        ax.tripcolor(  # type: ignore[call-overload]  # stubs lack (x, y, triangles, c)
            q[:, 0], q[:, 1], front, shade, cmap="Greys_r", vmin=0.0, vmax=1.15, shading="gouraud"
        )
    for c in curves:
        q = c @ r.T
        ax.plot(q[:, 0], q[:, 1], color="tab:orange", lw=0.7)
    if len(points):
        q = np.asarray(points) @ r.T
        ax.scatter(q[:, 0], q[:, 1], s=6, color="tab:red", zorder=3)
        _numbers(ax, q[:, :2], 5, 1)
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_axis_off()
    return ax
