"""preview.png: top view and perspective view of the tracked piece, taxels numbered."""

from __future__ import annotations

import numpy as np

PREVIEW_GRID_MM = 1.5  # spacing of the height field drawn in the perspective view
PREVIEW_GRID_MAX = 120  # ... at most this many points along the longer side


def height_field(verts: np.ndarray, up_faces: np.ndarray):
    """The piece's top as a regular height field for drawing: (X, Y, Z) (ny, nx) mm, Z the
    highest upward face over each grid point, NaN off the piece. A regular grid draws as
    a readable shaded surface where matplotlib's depth sorting of long thin triangles
    shows shards. Vectorized z-buffer: every (triangle, grid point in its box) pair once."""
    tri = verts[up_faces]  # (F, 3, 3)
    lo, hi = tri[..., :2].reshape(-1, 2).min(axis=0), tri[..., :2].reshape(-1, 2).max(axis=0)
    step = max(PREVIEW_GRID_MM, float((hi - lo).max()) / PREVIEW_GRID_MAX)
    nx, ny = int(np.ceil((hi[0] - lo[0]) / step)) + 1, int(np.ceil((hi[1] - lo[1]) / step)) + 1
    i0 = np.ceil((tri[..., 0].min(axis=1) - lo[0]) / step).astype(int)
    i1 = np.floor((tri[..., 0].max(axis=1) - lo[0]) / step).astype(int)
    j0 = np.ceil((tri[..., 1].min(axis=1) - lo[1]) / step).astype(int)
    j1 = np.floor((tri[..., 1].max(axis=1) - lo[1]) / step).astype(int)
    wi, wj = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
    count = wi * wj
    f = np.repeat(np.arange(len(tri)), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    gi, gj = i0[f] + k % wi[f], j0[f] + k // wi[f]
    px, py = lo[0] + gi * step, lo[1] + gj * step
    a, b, c = tri[f, 0], tri[f, 1], tri[f, 2]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    ok = np.abs(det) > 1e-12
    det = np.where(ok, det, 1.0)
    u = ((px - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (py - a[:, 1])) / det
    v = ((b[:, 0] - a[:, 0]) * (py - a[:, 1]) - (px - a[:, 0]) * (b[:, 1] - a[:, 1])) / det
    inside = ok & (u >= 0) & (v >= 0) & (u + v <= 1)
    z = a[:, 2] + u * (b[:, 2] - a[:, 2]) + v * (c[:, 2] - a[:, 2])
    zbuf = np.full(nx * ny, -np.inf)
    np.maximum.at(zbuf, (gj * nx + gi)[inside], z[inside])
    zbuf[~np.isfinite(zbuf)] = np.nan
    x, y = np.meshgrid(lo[0] + np.arange(nx) * step, lo[1] + np.arange(ny) * step)
    return x, y, zbuf.reshape(ny, nx)


def write_preview(path, top_v: np.ndarray, top_f: np.ndarray, curves: list[np.ndarray],
                  taxel_xyz: np.ndarray, title: str = "") -> None:
    """Save a two-panel PNG (mm axes) of the piece, its track curves and numbered taxels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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

    ax3 = fig.add_subplot(1, 2, 2, projection="3d", computed_zorder=False)
    x, y, z = height_field(top_v, top_f[facing_up])
    from matplotlib.colors import LightSource

    shaded = LightSource(azdeg=315, altdeg=50).shade(
        np.nan_to_num(z, nan=float(np.nanmin(z))), cmap=plt.cm.Greys_r, vert_exag=1.0,
        blend_mode="soft", vmin=float(np.nanmin(z)) - 0.5 * float(np.nanmax(z) - np.nanmin(z)),
        vmax=float(np.nanmax(z)))
    ax3.plot_surface(x, y, z, facecolors=shaded, rstride=1, cstride=1, linewidth=0,
                     antialiased=False, shade=False, zorder=1)
    lift = 0.4  # mm: curves and taxels drawn just above the surface so they stay visible
    for c in curves:
        ax3.plot(c[:, 0], c[:, 1], c[:, 2] + lift, color="tab:orange", lw=0.7, zorder=2)
    ax3.scatter(*(taxel_xyz + [0, 0, lift]).T, s=8, color="tab:red", depthshade=False,
                zorder=3)
    for t, p in enumerate(taxel_xyz):
        ax3.text(p[0], p[1], p[2] + 2.0, str(t), fontsize=5, zorder=4)
    lo, hi = top_v.min(axis=0), top_v.max(axis=0)
    ax3.set_xlim(lo[0], hi[0])
    ax3.set_ylim(lo[1], hi[1])
    ax3.set_zlim(lo[2], hi[2])
    ax3.set_box_aspect(hi - lo)  # to scale
    from matplotlib.ticker import MaxNLocator

    ax3.zaxis.set_major_locator(MaxNLocator(2))
    ax3.set_xlabel("x (mm)")
    ax3.set_ylabel("y (mm)")
    ax3.set_zlabel("z (mm)", labelpad=-2)
    ax3.tick_params(labelsize=7)
    ax3.view_init(elev=40, azim=-60)
    ax3.set_title("perspective")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
