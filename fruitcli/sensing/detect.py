"""Touch detection on the taxel grid (paper Sec. III-B): baseline, N9 centroid, multitouch.

Units: counts. Vectorized over frames: each round takes every frame's maximum at once;
rounds loop over touches per frame, never over frames.

Activation v = C - C0 clipped at 0, on a padded taxel grid (H, W) = (I + 2, J + 2) whose
border and cells without a taxel stay 0, so off-grid and missing cells count 0 in N9.
Ties of the maximum go to the first cell in row-major order (lowest i, then lowest j).

The batch N9 (`n9_sequential`) does not build that grid: it works on the frames' own
cells (or the taxels' counts in grid order, `Layout`) and reads the N9 neighbours
through a table, so a frame costs rows * cols (or T) numbers instead of H * W. The
weighted offsets sum the N9 terms in one fixed order (`n9_offsets`), so a touch's
i and j do not depend on how many frames are detected together.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fruitcli.errors import FrameError

MAX_TOUCHES = 10  # touches per frame at most (FT5316 reports up to 10 fingers)
# taxels on at least this share of the frame's cells: detect on the frames' own cells
# (no copy, but every cell is scanned); fewer: take the taxels' counts out first
FRAME_LAYOUT_SHARE = 0.6
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


def baseline_counts(frames: np.ndarray, k: int, where: str = "frames",
                    n_frames: int | None = None) -> np.ndarray:
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
    """Where the batch N9 keeps each taxel's v in a row of X numbers.

    When the board keeps the grid's row-major order (frame index increasing with (i, j)
    row-major, as the default board does) and taxels cover most of the frame
    (`FRAME_LAYOUT_SHARE`), a row is the frame itself: X = rows * cols, cells without a
    taxel hold v = -inf, and no copy of the frames is made. Otherwise the taxels' counts
    are taken into X = T columns in row-major grid order. Either way the
    first maximum of a row is the first in the grid's row-major order, as on the padded
    grid, and N9 cells without a taxel (or off the frame) read 0.
    """

    frame_cell: np.ndarray  # (T,) flat frame index of each taxel
    take: np.ndarray | None  # (X,) frame cells taken into a row, None: the frame's own
    width: int  # X
    column: np.ndarray  # (T,) row position of each taxel
    n9: np.ndarray  # (X, 9) row position of each N9 cell (-1: no taxel there)
    n9_taxel: np.ndarray  # (X, 9) taxel of each N9 cell (-1: none)
    ci: np.ndarray  # (X,) padded grid row of the taxel at each position
    cj: np.ndarray  # (X,) padded grid column

    @classmethod
    def build(cls, grid: Grid, frame_cell: np.ndarray, frame_size: int) -> Layout:
        """`frame_cell` (T,): flat frame index of each taxel; `frame_size`: rows * cols."""
        frame_cell = np.asarray(frame_cell, dtype=np.int64)
        order = np.argsort(grid.cell, kind="stable")  # taxels in row-major grid order
        in_order = bool(np.all(np.diff(frame_cell[order]) > 0))
        if in_order and order.size >= FRAME_LAYOUT_SHARE * frame_size:
            take, width, column = None, frame_size, frame_cell
        else:
            take, width = frame_cell[order], order.size
            column = np.empty(order.size, np.int64)
            column[order] = np.arange(order.size)
        pos_of_cell = np.full(grid.taxel_of_cell.size, -1, np.int64)
        pos_of_cell[grid.cell] = column
        n9 = np.full((width, 9), -1, np.int64)
        n9_taxel = np.full((width, 9), -1, np.int64)
        ci, cj = np.zeros(width, np.int64), np.zeros(width, np.int64)
        idx = grid.cell[:, None] + grid.offsets
        n9[column] = pos_of_cell[idx]
        n9_taxel[column] = grid.taxel_of_cell[idx]
        ci[column], cj[column] = np.divmod(grid.cell, grid.shape[1])
        return cls(frame_cell, take, width, column, n9, n9_taxel, ci, cj)

    def baseline_row(self, baseline: np.ndarray) -> np.ndarray:
        """C0 (T,) at the taxels' row positions, +inf elsewhere (X,)."""
        base = np.full(self.width, np.inf)
        base[self.column] = baseline
        return base

    def activations(self, frames: np.ndarray, base_row: np.ndarray,
                    out: np.ndarray | None = None) -> np.ndarray:
        """C - C0 (not clipped) of frames (N, rows * cols) in rows of X, as a flat
        (N * X + 1,) array whose last element is 0 (what N9 cells without a taxel read).
        `base_row` from `baseline_row`; `out`: a buffer of at least N * X + 1 to reuse."""
        n = frames.shape[0]
        size = n * self.width + 1
        buf = np.empty(size) if out is None or out.size < size else out[:size]
        src = frames if self.take is None else np.take(frames, self.take, axis=1)
        np.subtract(src, base_row, out=buf[:-1].reshape(n, self.width))
        buf[-1] = 0.0
        return buf


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
    di, dj = n9_offsets(w)
    i = (ci - 1) + di
    j = (cj - 1) + dj
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


def n9_sequential(buf: np.ndarray, layout: Layout, threshold: float, floor: float = 0.0,
                  max_touches: int = MAX_TOUCHES) -> Touches:
    """The paper's multitouch: take the maximum, N9 centroid, zero N9, repeat while
    some v > threshold. `buf` from `Layout.activations` (modified in place); the N9
    values are clipped at 0 as they are read, the centroids taken for all rounds at once."""
    if floor >= threshold:
        raise FrameError(f"noise floor {floor} counts must be below the threshold {threshold}")
    x = layout.width
    n = (buf.size - 1) // x
    v = buf[:-1].reshape(n, x)
    dump = buf.size - 1
    alive = np.arange(n)
    rounds = []  # (frames, cells, peaks, N9 values) of each round
    for _ in range(max_touches):
        if alive.size == 0:
            break
        if 5 * alive.size > n:  # many frames: one pass over all beats copying these
            k = v.argmax(axis=1)[alive]
        else:
            k = v[alive].argmax(axis=1)
        peak = buf[alive * x + k]
        hit = peak > threshold
        alive, k, peak = alive[hit], k[hit], peak[hit]
        if alive.size == 0:
            break
        nb = layout.n9[k]
        at = np.where(nb >= 0, alive[:, None] * x + nb, dump)
        rounds.append((alive, k, peak, buf[at]))
        buf[at] = 0.0
    if not rounds:
        return _collect([])
    frame = np.concatenate([f for f, *_ in rounds])
    rank = np.concatenate([np.full(f.size, r) for r, (f, *_) in enumerate(rounds)])
    count = np.bincount(frame, minlength=n)  # frame by frame, rank by rank:
    order = np.empty(frame.size, np.int64)
    order[(np.cumsum(count) - count)[frame] + rank] = np.arange(frame.size)
    frame, rank = frame[order], rank[order]
    k = np.concatenate([c for _, c, _, _ in rounds])[order]
    peak = np.concatenate([p for _, _, p, _ in rounds])[order]
    win = np.concatenate([w for *_, w in rounds])[order]
    win = np.maximum(win - floor, 0.0) if floor > 0 else np.maximum(win, 0.0)
    w = win / win.sum(axis=1, keepdims=True)
    di, dj = n9_offsets(w)
    return Touches(frame, rank, (layout.ci[k] - 1) + di, (layout.cj[k] - 1) + dj, peak,
                   layout.n9_taxel[k], w)


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


def detect(frames: np.ndarray, baseline: np.ndarray, grid: Grid, layout: Layout,
           threshold: float, method: str = "n9", floor: float = 0.0,
           max_touches: int = MAX_TOUCHES, base_row: np.ndarray | None = None,
           out: np.ndarray | None = None) -> Touches:
    """Touches of frames (N, rows * cols) counts against C0 (T,) by the scene's
    ``[detection].method``: n9 (paper), n9_floor or peaks. `base_row`
    (`Layout.baseline_row` of C0) and `out` (a buffer to reuse) save work per chunk."""
    if method in ("n9", "n9_floor"):
        if base_row is None:
            base_row = layout.baseline_row(baseline)
        return n9_sequential(layout.activations(frames, base_row, out), layout, threshold,
                             floor if method == "n9_floor" else 0.0, max_touches)
    if method == "peaks":
        values = np.take(frames, layout.frame_cell, axis=1)
        return n9_peaks(activation_grid(values, baseline, grid), grid, threshold, floor,
                        max_touches)
    raise FrameError(f"detection method: expected n9, n9_floor or peaks, got {method!r}")
