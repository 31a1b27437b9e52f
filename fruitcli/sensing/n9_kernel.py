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
def n9_scan(frames, cell, base, gain, divide, n9, threshold, max_touches, frame, rank, pos,
            peak, win):
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
