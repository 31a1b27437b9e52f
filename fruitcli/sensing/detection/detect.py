"""Touch detection on the taxel grid (paper Sec. III-B): baseline, N9 centroid, multitouch.

Units: counts.

Activation v = C - C0 clipped at 0, on a padded taxel grid (H, W) = (I + 2, J + 2) whose
border and cells without a taxel stay 0, so off-grid and missing cells count 0 in N9.
Ties of the maximum go to the first cell in row-major order (lowest i, then lowest j).

Gain division (``gain`` (T,), off by default): v = max(C - C0, 0) / g per taxel, with g
its calibrated gain (`fruit calibrate`'s gains.csv). Everything after that works on the
divided v: the threshold, the maxima, the N9 weights and the reported peak, all in
counts of a taxel of gain 1 (a taxel at half gain is detected and weighted as if at
full gain; its noise is doubled too).

The batch N9 (`n9_sequential`) does not build that grid: a compiled loop over the
frames (`n9_kernel`) reads each frame's taxel counts in row-major grid order (`Layout`)
and their N9 neighbours through a table; the centroids are vectorized over all touches,
as is the `peaks` method over frames. The weighted offsets sum the N9 terms in one
fixed order (`n9_offsets`), so a touch's i and j do not depend on how many frames are
detected together.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fruitcli.errors import FrameError

MAX_TOUCHES = 10  # touches per frame at most (FT5316 reports up to 10 fingers)
_DI = np.repeat(np.arange(-1, 2), 3)  # N9 row offsets, row-major
_DJ = np.tile(np.arange(-1, 2), 3)  # N9 column offsets


@dataclass
class Touches:
    """Touches of a batch of frames, sorted by frame then rank (strongest first)."""

    frame: np.ndarray  # (n,) int frame index within the batch
    rank: np.ndarray  # (n,) int 0 = first extracted in its frame
    i: np.ndarray  # (n,) float weighted grid coordinate
    j: np.ndarray  # (n,) float
    peak: np.ndarray  # (n,) float maximal activation v (counts)
    taxel: np.ndarray  # (n, 9) int taxel index of each N9 cell (-1: none)
    weight: np.ndarray  # (n, 9) float N9 weights w (sum 1)

    def __len__(self) -> int:
        return int(self.frame.shape[0])

    @classmethod
    def empty(cls) -> Touches:
        """No touch."""
        e = np.zeros(0)
        return cls(
            e.astype(np.int64),
            e.astype(np.int64),
            e,
            e,
            e,
            np.zeros((0, 9), np.int64),
            np.zeros((0, 9)),
        )


def baseline_counts(
    frames: np.ndarray, k: int, where: str = "frames", n_frames: int | None = None
) -> np.ndarray:
    """C0: mean of the first `k` frames (counts), shape of one frame. `n_frames`: the
    recording's length when `frames` holds only its first frames."""
    n = frames.shape[0] if n_frames is None else n_frames
    if k < 1:
        raise FrameError(f"{where}: baseline frames: expected >= 1, got {k}")
    if n < k:
        raise FrameError(f"{where}: {n} frames, fewer than the {k} baseline frames")
    return frames[:k].mean(axis=0)


@dataclass(frozen=True)
class Grid:
    """Taxel layout on the padded grid: flat cell of each taxel and taxel of each cell."""

    shape: tuple[int, int]  # padded (H, W)
    cell: np.ndarray  # (T,) flat padded cell of each taxel
    taxel_of_cell: np.ndarray  # (H * W,) taxel index or -1

    @classmethod
    def from_ij(cls, i: np.ndarray, j: np.ndarray) -> Grid:
        h, w = int(i.max()) + 3, int(j.max()) + 3
        cell = (np.asarray(i) + 1) * w + (np.asarray(j) + 1)
        tax = np.full(h * w, -1, dtype=np.int64)
        tax[cell] = np.arange(len(cell))
        return cls((h, w), cell.astype(np.int64), tax)

    @property
    def offsets(self) -> np.ndarray:
        """(9,) flat offsets of the N9 cells."""
        return _DI * self.shape[1] + _DJ


@dataclass(frozen=True)
class Layout:
    """The taxels in row-major grid order ("positions"), where the batch N9 works: each
    position's frame cell, N9 neighbours and padded grid cell. The first maximum over
    positions is the first in the grid's row-major order, as on the padded grid."""

    frame_cell: np.ndarray  # (T,) flat frame index of each taxel (file order)
    taxel: np.ndarray  # (T,) taxel at each position
    cell: np.ndarray  # (T,) flat frame index of each position
    n9: np.ndarray  # (T, 9) position of each N9 cell of a position (-1: no taxel there)
    n9_taxel: np.ndarray  # (T, 9) taxel of each N9 cell (-1: none)
    ci: np.ndarray  # (T,) padded grid row of each position
    cj: np.ndarray  # (T,) padded grid column

    @classmethod
    def build(cls, grid: Grid, frame_cell: np.ndarray) -> Layout:
        """`frame_cell` (T,): flat frame index of each taxel."""
        frame_cell = np.asarray(frame_cell, dtype=np.int64)
        order = np.argsort(grid.cell, kind="stable")  # taxels in row-major grid order
        column = np.empty(order.size, np.int64)
        column[order] = np.arange(order.size)
        pos_of_cell = np.full(grid.taxel_of_cell.size, -1, np.int64)
        pos_of_cell[grid.cell] = column
        idx = grid.cell[order][:, None] + grid.offsets
        ci, cj = np.divmod(grid.cell[order], grid.shape[1])
        return cls(
            frame_cell, order, frame_cell[order], pos_of_cell[idx], grid.taxel_of_cell[idx], ci, cj
        )


def n9_offsets(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted N9 offsets (sum_k w_k di_k, sum_k w_k dj_k) of weights w (n, 9).

    The terms are +-w_k or 0 (exact); they are summed in the order of the BLAS kernel
    that ``w @ di`` ran on whole recordings before (lanes k and k + 4, lanes (0 + 2) +
    (1 + 3), then term 8), the same for every row, however many are summed together.
    """
    c = [w[:, k] for k in range(9)]
    di = (((c[6] - c[2]) - c[0]) + (c[7] - c[1])) + c[8]
    dj = (((c[2] - c[6]) - c[0]) + (c[5] - c[3])) + c[8]
    return di, dj


def activation_grid(
    values: np.ndarray, baseline: np.ndarray, grid: Grid, gain: np.ndarray | None = None
) -> np.ndarray:
    """v = max(C - C0, 0) (/ gain) per taxel (N, T) -> padded flat grid (N, H * W) float64."""
    v = np.asarray(values, dtype=float) - baseline
    np.maximum(v, 0.0, out=v)
    if gain is not None:
        v /= gain
    out = np.zeros((v.shape[0], grid.shape[0] * grid.shape[1]))
    out[:, grid.cell] = v
    return out


def _centroids(flat: np.ndarray, rows: np.ndarray, centre: np.ndarray, grid: Grid, floor: float):
    """N9 windows around `centre` cells of frames `rows`: (i, j, taxel, weight, window idx)."""
    idx = centre[:, None] + grid.offsets
    win = flat[rows[:, None], idx]
    if floor > 0:
        win = np.maximum(win - floor, 0.0)
    w = win / win.sum(axis=1, keepdims=True)
    ci, cj = np.divmod(centre, grid.shape[1])
    di, dj = n9_offsets(w)
    i = (ci - 1) + di
    j = (cj - 1) + dj
    return i, j, grid.taxel_of_cell[idx], w, idx


def _collect(parts: list[tuple]) -> Touches:
    if not parts:
        return Touches.empty()
    cols = [np.concatenate(c) for c in zip(*parts, strict=True)]
    frame, rank = cols[0], cols[1]
    order = np.lexsort((rank, frame))
    return Touches(*(c[order] for c in cols))


def n9_sequential(
    frames: np.ndarray,
    baseline: np.ndarray,
    layout: Layout,
    threshold: float,
    floor: float = 0.0,
    max_touches: int = MAX_TOUCHES,
    gain: np.ndarray | None = None,
) -> Touches:
    """The paper's multitouch on frames (N, rows * cols) counts against C0 (T,): take the
    maximum, N9 centroid, zero N9, repeat while some v > threshold (v divided by `gain`
    (T,) when given). The extraction runs compiled frame by frame
    (`n9_kernel.n9_scan`), the centroids vectorized."""
    from fruitcli.sensing.detection.n9_kernel import n9_scan

    if floor >= threshold:
        raise FrameError(f"noise floor {floor} counts must be below the threshold {threshold}")
    n = frames.shape[0]
    cap = n * max_touches
    frame, rank, pos = (np.empty(cap, np.int64) for _ in range(3))
    peak, win = np.empty(cap), np.empty((cap, 9))
    base = np.asarray(baseline, dtype=float)[layout.taxel]
    g = np.ones(base.size) if gain is None else np.asarray(gain, dtype=float)[layout.taxel]
    count = n9_scan(
        np.ascontiguousarray(frames, dtype=np.int64),
        layout.cell,
        base,
        g,
        gain is not None,
        layout.n9,
        float(threshold),
        int(max_touches),
        frame,
        rank,
        pos,
        peak,
        win,
    )
    if count == 0:
        return _collect([])
    k = pos[:count]
    win = win[:count]
    win = np.maximum(win - floor, 0.0) if floor > 0 else np.maximum(win, 0.0)
    w = win / win.sum(axis=1, keepdims=True)
    di, dj = n9_offsets(w)
    return Touches(
        frame[:count].copy(),
        rank[:count].copy(),
        (layout.ci[k] - 1) + di,
        (layout.cj[k] - 1) + dj,
        peak[:count].copy(),
        layout.n9_taxel[k],
        w,
    )


def local_peaks(flat: np.ndarray, grid: Grid, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """Cells with v > threshold that beat their 8 neighbours: strictly those before them in
    row-major order, or equal those after (a plateau yields one peak). -> (frame, cell)."""
    h, w = grid.shape
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


def n9_peaks(
    flat: np.ndarray,
    grid: Grid,
    threshold: float,
    floor: float = 0.0,
    max_touches: int = MAX_TOUCHES,
) -> Touches:
    """Peak-based multitouch: every local maximum's N9 centroid on the unmodified v, so
    the result does not depend on the order of extraction. Ranked by peak value."""
    if floor >= threshold:
        raise FrameError(f"noise floor {floor} counts must be below the threshold {threshold}")
    f, cell = local_peaks(flat, grid, threshold)
    if f.size == 0:
        return _collect([])
    peak = flat[f, cell]
    order = np.lexsort((cell, -peak, f))
    f, cell, peak = f[order], cell[order], peak[order]
    start = np.r_[0, np.flatnonzero(np.diff(f)) + 1]
    rank = np.arange(f.size) - np.repeat(start, np.diff(np.r_[start, f.size]))
    keep = rank < max_touches
    f, cell, peak, rank = f[keep], cell[keep], peak[keep], rank[keep]
    i, j, tax, w, _ = _centroids(flat, f, cell, grid, floor)
    return Touches(f, rank, i, j, peak, tax, w)
