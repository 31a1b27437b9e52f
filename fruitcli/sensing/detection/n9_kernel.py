"""Compiled frame loop (numba) of the batch N9: activations, maxima and N9 zeroing.

Units: counts. One pass per frame over its taxels instead of numpy's passes over whole
chunks; it only moves and compares numbers (v = C - C0 is the same IEEE subtraction
numpy does), so the touches are exactly those of the vectorized loop. The centroids
(weights, offsets) stay in numpy. Releases the GIL, so chunks run on several threads.
Compiled (or loaded from numba's disk cache) on first use.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def n9_scan(
    frames, cell, base, gain, divide, n9, threshold, max_touches, frame, rank, pos, peak, win
) -> int:
    """Multitouch N9 extraction on frames (n, S) counts; taxel p (in row-major grid order)
    is frame cell cell[p] with baseline base[p], its N9 neighbours n9[p] (-1: none).
    v = C - C0, divided by gain[p] when `divide`; while the first maximum of v is >
    threshold (and fewer than `max_touches`): record frame, rank, position, peak and the
    9 values of v in its N9 (0 where there is no taxel), then zero them. Writes rows
    0 .. count - 1 of the output arrays (capacity n * max_touches), frame by frame, rank
    by rank; returns count."""
    n = frames.shape[0]
    t = cell.shape[0]
    v = np.empty(t)
    count = 0
    for f in range(n):
        best = -np.inf
        k = -1
        above = 0  # values > threshold left: none, and no later maximum can exceed it
        for p in range(t):
            x = np.float64(frames[f, cell[p]]) - base[p]
            if divide:
                x = x / gain[p]
            v[p] = x
            if x > best:
                best = x
                k = p
            if x > threshold:
                above += 1
        for r in range(max_touches):
            if r > 0:
                if above == 0:
                    break
                best = -np.inf
                k = -1
                for p in range(t):
                    if v[p] > best:
                        best = v[p]
                        k = p
            if not best > threshold:
                break
            frame[count] = f
            rank[count] = r
            pos[count] = k
            peak[count] = best
            for q in range(9):
                m = n9[k, q]
                if m >= 0:
                    if v[m] > threshold:
                        above -= 1
                    win[count, q] = v[m]
                    v[m] = 0.0
                else:
                    win[count, q] = 0.0
            count += 1
    return count


@njit(cache=True, nogil=True)
def n9_frame(
    v, taxel, n9, ci, cj, threshold, floor, max_touches, scratch, pos, peak, i, j, w
) -> int:
    """The paper's N9 loop on one frame (the live loop's `Stream`): activations v (T,)
    (clipped at 0, in taxel order) are copied into `scratch` (T,) in row-major grid
    order (taxel[p] at position p); while the first maximum is > threshold (and fewer
    than `max_touches`): the N9 window (0 where there is no taxel; minus `floor`,
    clipped at 0, when floor > 0), its weights w (9,) = window / sum, the centroid
    i = ci - 1 + sum_k w_k di_k, j likewise, then the window is zeroed. Fills rows
    0 .. count - 1 of pos, peak, i, j (max_touches,) and w (max_touches, 9); -> count.

    Every sum runs in the order numpy used for the same numbers before (the per-touch
    ``win.sum()``: pairwise, lanes 0-7 in pairs then term 8; ``w @ di``: term by term
    from 0.0, as OpenBLAS's ddot does below 16 terms), so the touches are the same to
    the bit (tests/test_sensing_live_kernel.py)."""
    t = taxel.shape[0]
    for p in range(t):
        scratch[p] = v[taxel[p]]
    win = np.empty(9)
    count = 0
    for _ in range(max_touches):
        best = -np.inf
        k = -1
        for p in range(t):
            if scratch[p] > best:
                best = scratch[p]
                k = p
        if not best > threshold:
            break
        for q in range(9):
            m = n9[k, q]
            x = scratch[m] if m >= 0 else 0.0
            if floor > 0:
                x = max(x - floor, 0.0)
            win[q] = x
        total = (
            ((win[0] + win[1]) + (win[2] + win[3])) + ((win[4] + win[5]) + (win[6] + win[7]))
        ) + win[8]
        di = 0.0
        dj = 0.0
        for q in range(9):
            wq = win[q] / total
            w[count, q] = wq
            di += wq * (q // 3 - 1)
            dj += wq * (q % 3 - 1)
        pos[count] = k
        peak[count] = best
        i[count] = (ci[k] - 1) + di
        j[count] = (cj[k] - 1) + dj
        for q in range(9):
            m = n9[k, q]
            if m >= 0:
                scratch[m] = 0.0
        count += 1
    return count
