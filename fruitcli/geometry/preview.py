"""preview.png: top view and perspective view of the tracked piece, taxels numbered."""

from __future__ import annotations

import numpy as np

# triangles drawn in the perspective view at most (every k-th face beyond this)
MAX_PREVIEW_FACES = 12000


def write_preview(path, top_v: np.ndarray, top_f: np.ndarray, curves: list[np.ndarray],
                  taxel_xyz: np.ndarray, title: str = "") -> None:
    """Save a two-panel PNG (mm axes) of the piece, its track curves and numbered taxels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = plt.figure(figsize=(13, 6), dpi=110)
    ax = fig.add_subplot(1, 2, 1)
    t = top_v[top_f]
    facing_up = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])[:, 2] > 0
    ax.tripcolor(top_v[:, 0], top_v[:, 1], top_f[facing_up], top_v[:, 2],
                 cmap="Greys", shading="gouraud", alpha=0.8)
    for c in curves:
        ax.plot(c[:, 0], c[:, 1], color="tab:orange", lw=0.8)
    ax.scatter(taxel_xyz[:, 0], taxel_xyz[:, 1], s=10, color="tab:red", zorder=3)
    for k, p in enumerate(taxel_xyz):
        ax.annotate(str(k), p[:2], fontsize=6, xytext=(2, 2), textcoords="offset points")
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title("top view")

    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
    faces = top_f[:: max(1, len(top_f) // MAX_PREVIEW_FACES)]
    tri = top_v[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    light = np.array([0.3, -0.4, 0.87])
    shade = 0.35 + 0.6 * np.clip(n @ light, 0, 1)
    coll = Poly3DCollection(tri, facecolors=plt.cm.Greys(1 - shade * 0.8), linewidths=0)
    ax3.add_collection3d(coll)
    for c in curves:
        ax3.plot(c[:, 0], c[:, 1], c[:, 2] + 0.3, color="tab:orange", lw=0.7)
    ax3.scatter(*taxel_xyz.T, s=6, color="tab:red", depthshade=False)
    for t, p in enumerate(taxel_xyz):
        ax3.text(p[0], p[1], p[2] + 1.0, str(t), fontsize=5)
    lo, hi = top_v.min(axis=0), top_v.max(axis=0)
    ax3.set_xlim(lo[0], hi[0])
    ax3.set_ylim(lo[1], hi[1])
    ax3.set_zlim(lo[2], hi[2])
    ax3.set_box_aspect(hi - lo)
    ax3.view_init(elev=35, azim=-60)
    ax3.set_title("perspective")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
