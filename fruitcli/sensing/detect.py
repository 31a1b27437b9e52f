"""Touch detection on the taxel grid (paper Sec. III-B): baseline, N9 centroid, multitouch.

Units: counts. Vectorized over frames: each round takes every frame's maximum at once;
rounds loop over touches per frame, never over frames.

Activation v = C - C0 clipped at 0, on a padded taxel grid (H, W) = (I + 2, J + 2) whose
border and cells without a taxel stay 0, so off-grid and missing cells count 0 in N9.
Ties of the maximum go to the first cell in row-major order (lowest i, then lowest j).
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


def baseline_counts(frames: np.ndarray, k: int, where: str = "frames") -> np.ndarray:
    """C0: mean of the first `k` frames (counts), shape of one frame."""
    if k < 1:
        raise FrameError(f"{where}: baseline frames: expected >= 1, got {k}")
    if frames.shape[0] < k:
        raise FrameError(f"{where}: {frames.shape[0]} frames, fewer than the {k} baseline "
                         "frames")
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


def activation_grid(values: np.ndarray, baseline: np.ndarray, grid: Grid) -> np.ndarray:
    """v = max(C - C0, 0) per taxel (N, T) -> padded flat grid (N, H * W) float64."""
    v = np.asarray(values, dtype=float) - baseline
    np.maximum(v, 0.0, out=v)
    out = np.zeros((v.shape[0], grid.shape[0] * grid.shape[1]))
    out[:, grid.cell] = v
    return out


def _centroids(flat: np.ndarray, rows: np.ndarray, centre: np.ndarray, grid: Grid,
               floor: float):
    """N9 windows around `centre` cells of frames `rows`: (i, j, taxel, weight, window idx)."""
    idx = centre[:, None] + grid.offsets
    win = flat[rows[:, None], idx]
    if floor > 0:
        win = np.maximum(win - floor, 0.0)
    w = win / win.sum(axis=1, keepdims=True)
    ci, cj = np.divmod(centre, grid.shape[1])
    i = (ci - 1) + w @ _DI
    j = (cj - 1) + w @ _DJ
    return i, j, grid.taxel_of_cell[idx], w, idx


def _collect(parts: list[tuple]) -> Touches:
    if not parts:
        e = np.zeros(0)
        return Touches(e.astype(np.int64), e.astype(np.int64), e, e, e,
                       np.zeros((0, 9), np.int64), np.zeros((0, 9)))
    cols = [np.concatenate(c) for c in zip(*parts, strict=True)]
    frame, rank = cols[0], cols[1]
    order = np.lexsort((rank, frame))
    return Touches(*(c[order] for c in cols))


def n9_sequential(flat: np.ndarray, grid: Grid, threshold: float, floor: float = 0.0,
                  max_touches: int = MAX_TOUCHES) -> Touches:
    """The paper's multitouch: take the maximum, N9 centroid, zero N9, repeat while
    some v > threshold. `flat` (N, H*W) padded activations (modified in place)."""
    if floor >= threshold:
        raise FrameError(f"noise floor {floor} counts must be below the threshold {threshold}")
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
        i, j, tax, w, idx = _centroids(flat, alive, k, grid, floor)
        parts.append((alive, np.full(alive.size, r), i, j, peak, tax, w))
        flat[alive[:, None], idx] = 0.0
    return _collect(parts)


def local_peaks(flat: np.ndarray, grid: Grid, threshold: float) -> tuple[np.ndarray,
                                                                         np.ndarray]:
    """Cells with v > threshold that beat their 8 neighbours: strictly those before them in
    row-major order, or equal those after (a plateau yields one peak). -> (frame, cell)."""
    h, w = grid.shape
    v = flat.reshape(-1, h, w)
    inner = v[:, 1:-1, 1:-1]
    ok = inner > threshold
    for di, dj in zip(_DI, _DJ, strict=True):
        if di == 0 and dj == 0:
            continue
        nb = v[:, 1 + di:h - 1 + di, 1 + dj:w - 1 + dj]
        before = di < 0 or (di == 0 and dj < 0)
        ok &= (inner > nb) if before else (inner >= nb)
    f, ci, cj = np.nonzero(ok)
    return f, (ci + 1) * w + (cj + 1)


def n9_peaks(flat: np.ndarray, grid: Grid, threshold: float, floor: float = 0.0,
             max_touches: int = MAX_TOUCHES) -> Touches:
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


def detect(flat: np.ndarray, grid: Grid, threshold: float, method: str = "n9",
           floor: float = 0.0, max_touches: int = MAX_TOUCHES) -> Touches:
    """Dispatch on the scene's ``[detection].method``: n9 (paper), n9_floor or peaks."""
    if method == "n9":
        return n9_sequential(flat, grid, threshold, 0.0, max_touches)
    if method == "n9_floor":
        return n9_sequential(flat, grid, threshold, floor, max_touches)
    if method == "peaks":
        return n9_peaks(flat, grid, threshold, floor, max_touches)
    raise FrameError(f"detection method: expected n9, n9_floor or peaks, got {method!r}")
