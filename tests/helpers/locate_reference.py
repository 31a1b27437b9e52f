"""The batch `fruit locate` in its first form (before recordings were read and detected in
chunks), frozen here as the reference that the fast path must reproduce byte for byte.

Copied from fruitcli/sensing/{detect,pipeline,locate,stage}.py and fruitcli/fsutil.py
of that commit, cut down to the stateless batch path (whole recording in memory, one
padded activation grid, rows written by the csv module with "%.6f" floats). Only numpy
and the csv module are used, so later changes to fruitcli cannot move it.
"""

from __future__ import annotations

import csv
import io

import numpy as np

_DI = np.repeat(np.arange(-1, 2), 3)
_DJ = np.tile(np.arange(-1, 2), 3)
HEADER = ["frame", "t_s", "touch", "i", "j", "x_mm", "y_mm", "z_mm", "peak"]


def grid_from_ij(i, j):
    h, w = int(i.max()) + 3, int(j.max()) + 3
    cell = (np.asarray(i) + 1) * w + (np.asarray(j) + 1)
    tax = np.full(h * w, -1, dtype=np.int64)
    tax[cell] = np.arange(len(cell))
    return (h, w), cell.astype(np.int64), tax


def activation_grid(values, baseline, shape, cell):
    v = np.asarray(values, dtype=float) - baseline
    np.maximum(v, 0.0, out=v)
    out = np.zeros((v.shape[0], shape[0] * shape[1]))
    out[:, cell] = v
    return out


def _centroids(flat, rows, centre, shape, tax_of_cell, floor):
    idx = centre[:, None] + (_DI * shape[1] + _DJ)
    win = flat[rows[:, None], idx]
    if floor > 0:
        win = np.maximum(win - floor, 0.0)
    w = win / win.sum(axis=1, keepdims=True)
    ci, cj = np.divmod(centre, shape[1])
    i = (ci - 1) + w @ _DI
    j = (cj - 1) + w @ _DJ
    return i, j, tax_of_cell[idx], w, idx


def _collect(parts):
    if not parts:
        e = np.zeros(0)
        return (
            e.astype(np.int64),
            e.astype(np.int64),
            e,
            e,
            e,
            np.zeros((0, 9), np.int64),
            np.zeros((0, 9)),
        )
    cols = [np.concatenate(c) for c in zip(*parts, strict=True)]
    order = np.lexsort((cols[1], cols[0]))
    return tuple(c[order] for c in cols)


def n9_sequential(flat, shape, tax_of_cell, threshold, floor, max_touches):
    alive = np.arange(flat.shape[0])
    parts = []
    for r in range(max_touches):
        if alive.size == 0:
            break
        sub = flat[alive]
        k = sub.argmax(axis=1)
        peak = sub[np.arange(alive.size), k]
        hit = peak > threshold
        alive, k, peak = alive[hit], k[hit], peak[hit]
        if alive.size == 0:
            break
        i, j, tax, w, idx = _centroids(flat, alive, k, shape, tax_of_cell, floor)
        parts.append((alive, np.full(alive.size, r), i, j, peak, tax, w))
        flat[alive[:, None], idx] = 0.0
    return _collect(parts)


def local_peaks(flat, shape, threshold):
    h, w = shape
    v = flat.reshape(-1, h, w)
    inner = v[:, 1:-1, 1:-1]
    ok = inner > threshold
    for di, dj in zip(_DI, _DJ, strict=True):
        if di == 0 and dj == 0:
            continue
        nb = v[:, 1 + di : h - 1 + di, 1 + dj : w - 1 + dj]
        before = di < 0 or (di == 0 and dj < 0)
        ok &= (inner > nb) if before else (inner >= nb)
    f, ci, cj = np.nonzero(ok)
    return f, (ci + 1) * w + (cj + 1)


def n9_peaks(flat, shape, tax_of_cell, threshold, floor, max_touches):
    f, cell = local_peaks(flat, shape, threshold)
    if f.size == 0:
        return _collect([])
    peak = flat[f, cell]
    order = np.lexsort((cell, -peak, f))
    f, cell, peak = f[order], cell[order], peak[order]
    start = np.r_[0, np.flatnonzero(np.diff(f)) + 1]
    rank = np.arange(f.size) - np.repeat(start, np.diff(np.r_[start, f.size]))
    keep = rank < max_touches
    f, cell, peak, rank = f[keep], cell[keep], peak[keep], rank[keep]
    i, j, tax, w, _ = _centroids(flat, f, cell, shape, tax_of_cell, floor)
    return f, rank, i, j, peak, tax, w


def state_path_position(p, sp):
    n, s = p.shape[0], sp.shape[0]
    if s == 1:
        return np.zeros(n, np.int64), np.zeros(n)
    best_d = np.full(n, np.inf)
    seg, frac = np.zeros(n, np.int64), np.zeros(n)
    for k in range(s - 1):
        a, d = sp[k], sp[k + 1] - sp[k]
        dd = float(d @ d)
        t = np.zeros(n) if dd < 1e-12 else np.clip((p - a) @ d / dd, 0.0, 1.0)
        dist = np.sum((p - a - t[:, None] * d) ** 2, axis=1)
        better = dist < best_d
        best_d[better], seg[better], frac[better] = dist[better], k, t[better]
    return seg, frac


def touches_3d(frame, taxel, weight, positions, seg, frac):
    tax = np.where(taxel < 0, 0, taxel)
    if positions.ndim == 2:
        return np.einsum("nk,nkd->nd", weight, positions[tax])
    s_last = positions.shape[0] - 1
    s0 = seg[frame]
    s1 = np.minimum(s0 + 1, s_last)
    t = frac[frame][:, None]
    p0 = np.einsum("nk,nkd->nd", weight, positions[s0[:, None], tax])
    p1 = np.einsum("nk,nkd->nd", weight, positions[s1[:, None], tax])
    return (1.0 - t) * p0 + t * p1


def locate(
    frames,
    t_s,
    taxel_i,
    taxel_j,
    rows,
    cols,
    positions,
    threshold=20.0,
    baseline_frames=10,
    method="n9",
    floor=0.0,
    max_touches=10,
    pressure=None,
    state_pressure=None,
):
    """Touch table (frame, touch, i, j, xyz (n, 3), peak) as the batch path computed it."""
    values = frames[:, rows, cols]
    baseline = values[:baseline_frames].mean(axis=0)
    shape, cell, tax_of_cell = grid_from_ij(taxel_i, taxel_j)
    flat = activation_grid(values, baseline, shape, cell)
    floor = floor if method != "n9" else 0.0
    if method == "peaks":
        t = n9_peaks(flat, shape, tax_of_cell, threshold, floor, max_touches)
    else:
        t = n9_sequential(flat, shape, tax_of_cell, threshold, floor, max_touches)
    frame, rank, i, j, peak, tax, w = t
    seg = frac = None
    if positions.ndim == 3:
        seg, frac = (
            (np.zeros(len(frames), np.int64), np.zeros(len(frames)))
            if pressure is None
            else state_path_position(pressure, state_pressure)
        )
    xyz = touches_3d(frame, tax, w, positions, seg, frac)
    return frame, rank, i, j, xyz, peak


def touches_csv_text(table, t_s, comment: str) -> str:
    """touches.csv as fsutil.write_csv wrote it."""
    frame, touch, i, j, xyz, peak = table

    def fmt(v):
        return f"{v:.6f}" if isinstance(v, float) else str(v)

    buf = io.StringIO()
    buf.write(f"# {comment}\n")
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(HEADER)
    for n in range(len(frame)):
        f = int(frame[n])
        x, y, z = xyz[n]
        row = [
            f,
            float(t_s[f]),
            int(touch[n]),
            float(i[n]),
            float(j[n]),
            float(x),
            float(y),
            float(z),
            float(peak[n]),
        ]
        writer.writerow([fmt(v) for v in row])
    return buf.getvalue()
