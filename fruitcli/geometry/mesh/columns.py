"""Vertical rays through a triangle mesh: where the line x = px, y = py crosses the surface.

Used for the top height of a mesh at given (x, y) and for inside/outside parity of grid
points (no rtree needed). Points are `(n, 2)` or `(n, 3)` float64 in mm.
"""

from __future__ import annotations

from typing import Literal, overload

import numpy as np

# Query points are nudged by this much (mm) so that a ray never runs exactly through an
# edge or a vertex of a mesh whose coordinates are round numbers (a double count).
RAY_JITTER_MM = np.array([3.1e-7, 1.7e-7])


@overload
def vertical_hits(
    vertices: np.ndarray,
    faces: np.ndarray,
    xy: np.ndarray,
    cell_mm: float | None = None,
    upward: Literal[False] = False,
) -> tuple[np.ndarray, np.ndarray]: ...


@overload
def vertical_hits(
    vertices: np.ndarray,
    faces: np.ndarray,
    xy: np.ndarray,
    cell_mm: float | None = None,
    *,
    upward: Literal[True],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


def vertical_hits(
    vertices: np.ndarray,
    faces: np.ndarray,
    xy: np.ndarray,
    cell_mm: float | None = None,
    upward: bool = False,
) -> tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All crossings of vertical lines through `xy` (n, 2) with the triangles.

    Returns (point_index (h,) int, z_mm (h,) float), sorted by point then z; with
    `upward`, also (h,) bool: the crossed face's normal points up (+z).
    Triangles and points are matched through a uniform grid of `cell_mm` cells
    (default: the median triangle extent), so the cost is about linear.
    """
    xy = np.asarray(xy, dtype=float)[:, :2] + RAY_JITTER_MM
    tri = np.asarray(vertices, dtype=float)[np.asarray(faces)]
    if len(xy) == 0 or len(tri) == 0:
        none = np.zeros(0, dtype=np.int64), np.zeros(0)
        return (*none, np.zeros(0, dtype=bool)) if upward else none
    lo, hi = tri[:, :, :2].min(axis=1), tri[:, :, :2].max(axis=1)
    if cell_mm is None:
        cell_mm = float(max(np.median(hi - lo), 1e-3))
    origin = np.minimum(lo.min(axis=0), xy.min(axis=0))
    pc = np.floor((xy - origin) / cell_mm).astype(np.int64)
    ny = int(max(pc[:, 1].max(), np.floor((hi[:, 1].max() - origin[1]) / cell_mm))) + 2
    pkey = pc[:, 0] * ny + pc[:, 1]
    order = np.argsort(pkey, kind="stable")
    skey = pkey[order]

    c0 = np.floor((lo - origin) / cell_mm).astype(np.int64)
    c1 = np.floor((hi - origin) / cell_mm).astype(np.int64)
    nx_c, ny_c = c1[:, 0] - c0[:, 0] + 1, c1[:, 1] - c0[:, 1] + 1
    ncell = nx_c * ny_c
    t_idx = np.repeat(np.arange(len(tri)), ncell)
    local = np.arange(ncell.sum()) - np.repeat(np.cumsum(ncell) - ncell, ncell)
    cx = c0[t_idx, 0] + local // ny_c[t_idx]
    cy = c0[t_idx, 1] + local % ny_c[t_idx]
    ckey = cx * ny + cy
    start = np.searchsorted(skey, ckey, side="left")
    stop = np.searchsorted(skey, ckey, side="right")
    n = stop - start
    keep = n > 0
    t_idx, start, n = t_idx[keep], start[keep], n[keep]
    pair_t = np.repeat(t_idx, n)
    pair_p = order[np.repeat(start, n) + np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)]

    a, b, c = tri[pair_t, 0], tri[pair_t, 1], tri[pair_t, 2]
    p = xy[pair_p]
    d = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (
            (b[:, 0] - p[:, 0]) * (c[:, 1] - p[:, 1]) - (c[:, 0] - p[:, 0]) * (b[:, 1] - p[:, 1])
        ) / d
        v = (
            (c[:, 0] - p[:, 0]) * (a[:, 1] - p[:, 1]) - (a[:, 0] - p[:, 0]) * (c[:, 1] - p[:, 1])
        ) / d
        w = 1.0 - u - v
        hit = (d != 0) & (u >= 0) & (v >= 0) & (w >= 0)
        z = u * a[:, 2] + v * b[:, 2] + w * c[:, 2]
    pi, zi = pair_p[hit], z[hit]
    o = np.lexsort((zi, pi))
    if upward:
        return pi[o], zi[o], (d[hit] > 0)[o]
    return pi[o], zi[o]


def top_z(vertices: np.ndarray, faces: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Highest surface z (mm) above each (x, y) in `xy` (n, 2); NaN where the line misses."""
    pi, z = vertical_hits(vertices, faces, xy)
    out = np.full(len(xy), np.nan)
    np.fmax.at(out, pi, z)
    return out


def inside_columns(
    vertices: np.ndarray, faces: np.ndarray, xy: np.ndarray, z_mm: np.ndarray
) -> np.ndarray:
    """Inside/outside of a closed mesh on a grid of columns: point (k, m) is (xy[k], z_mm[m]).

    Returns a (len(xy), len(z_mm)) bool array by ray parity (hits above each point).
    """
    pi, zh = vertical_hits(vertices, faces, xy)
    z_mm = np.asarray(z_mm, dtype=float)
    # per column, the number of hits with z > z_m = hits in column - hits with z <= z_m
    col_start = np.searchsorted(pi, np.arange(len(xy)), side="left")
    col_stop = np.searchsorted(pi, np.arange(len(xy)), side="right")
    # a global sort key: column index plus z scaled into [0, 1) keeps the per-column order
    span = max(float(np.ptp(np.concatenate([zh, z_mm]))), 1.0) if len(zh) else 1.0
    zmin = min(float(zh.min()) if len(zh) else 0.0, float(z_mm.min()))
    key_hits = pi + (zh - zmin) / (span * 1.0001 + 1e-9)
    key_q = np.arange(len(xy))[:, None] + (z_mm[None, :] - zmin) / (span * 1.0001 + 1e-9)
    below = np.searchsorted(key_hits, key_q, side="right") - col_start[:, None]
    above = (col_stop - col_start)[:, None] - below
    return (above % 2) == 1
