"""Compiled touch shapes (numba) for the Gaussian skin's gap law: `touch_shape` per touch
in one loop, for the live loop's per-frame budget; `gathered_shapes` also gathers each
touch's activations and taxel positions from the frames, for the batch path.

Units: counts, mm. The same formulas as `touch_shape.footprint_fit` and
`touch_shape.touch_shapes` with a `heights.GapLaw` (tests/test_touch_shapes.py compares
them).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_LO = (1, 3)  # N9 cells before the centre (4) along i, along j
_HI = (7, 5)


@njit(cache=True, nogil=True)
def gap_law_shapes(
    v9, tax9, pos9, xyz, contact, decay, sigma, noise, gain, min_counts, out
) -> None:
    """out[k] = (strength, size_mm, height_mm, height_err_mm) of touch k from its N9
    activations v9 (n, 9), taxels tax9 (n, 9) (-1: none), positions pos9 (n, 9, 3),
    reported point xyz (n, 3); gain (T,) the model's taxel gains (ones: none)."""
    for k in range(v9.shape[0]):
        _shape(
            v9[k], tax9[k], pos9[k], xyz[k], contact, decay, sigma, noise, gain, min_counts, out[k]
        )


@njit(cache=True, nogil=True)
def gathered_shapes(
    counts,
    frame,
    cell,
    base,
    divide,
    tax9,
    pos,
    pos_row,
    xyz,
    contact,
    decay,
    sigma,
    noise,
    gain,
    min_counts,
    out,
) -> None:
    """`gap_law_shapes` of touches k with v9[k, q] = max(counts[frame[k], cell[t]] - base[t],
    0) / divide[t] for t = tax9[k, q] (0 where t < 0; divide empty: no division) and
    pos9[k, q] = pos[pos_row[k, q]]: counts (N, R * C) frames, cell (T,) each taxel's
    cell, base (T,) C0, pos (P, 3) mm."""
    v9 = np.empty(9)
    pos9 = np.empty((9, 3))
    for k in range(tax9.shape[0]):
        f = frame[k]
        for q in range(9):
            t = tax9[k, q]
            if t < 0:
                v9[q] = 0.0
            else:
                v = max(counts[f, cell[t]] - base[t], 0.0)
                v9[q] = v / divide[t] if divide.shape[0] > 0 else v
            for d in range(3):
                pos9[q, d] = pos[pos_row[k, q], d]
        _shape(v9, tax9[k], pos9, xyz[k], contact, decay, sigma, noise, gain, min_counts, out[k])


@njit(cache=True, nogil=True)
def _shape(v9, tax9, pos9, xyz, contact, decay, sigma, noise, gain, min_counts, out):
    """out = (strength, size_mm, height_mm, height_err_mm) of one touch: v9 (9,), tax9 (9,),
    pos9 (9, 3), xyz (3,). The centre (cx, cy, cz) and axis u in scalars: no allocation."""
    cx, cy, cz = xyz[0], xyz[1], xyz[2]
    px, py, pz = pos9[4, 0], pos9[4, 1], pos9[4, 2]
    curv = 0.0
    used = 0
    l0 = math.log(max(v9[4], min_counts))
    for axis in range(2):
        lo = _LO[axis]
        hi = _HI[axis]
        ax, ay, az = px - pos9[lo, 0], py - pos9[lo, 1], pz - pos9[lo, 2]
        bx, by, bz = pos9[hi, 0] - px, pos9[hi, 1] - py, pos9[hi, 2] - pz
        a = math.sqrt(ax**2 + ay**2 + az**2)
        b = math.sqrt(bx**2 + by**2 + bz**2)
        has_lo = v9[lo] > min_counts and a > 0
        has_hi = v9[hi] > min_counts and b > 0
        if not (has_lo or has_hi):
            continue
        if a == 0:
            a = 1.0
        if b == 0:
            b = 1.0
        llo = math.log(max(v9[lo], min_counts))
        lhi = math.log(max(v9[hi], min_counts))
        up = (lhi - l0) / b
        down = (l0 - llo) / a
        c2 = (up - down) / (a + b)
        both = has_lo and has_hi and c2 < 0
        if both:
            delta = -(up - c2 * b) / (2 * c2)
            curv += -2 * c2
            used += 1
        elif has_lo != has_hi:
            xn = b if has_hi else -a
            ratio = l0 - (lhi if has_hi else llo)
            delta = (xn * xn - 2 * sigma * sigma * ratio) / (2 * xn)
        else:
            continue
        delta = min(max(delta, -a / 2), b / 2)
        ab = a + b
        ux, uy, uz = (ax + bx) / ab, (ay + by) / ab, (az + bz) / ab
        norm = max(math.sqrt(ux * ux + uy * uy + uz * uz), 1e-12)
        ux, uy, uz = ux / norm, uy / norm, uz / norm
        along = delta + (px - cx) * ux + (py - cy) * uy + (pz - cz) * uz
        cx, cy, cz = cx + along * ux, cy + along * uy, cz + along * uz
    vm = 0.0
    mm = 0.0
    s2 = sigma * sigma
    for q in range(9):
        t = tax9[q]
        if t < 0:
            continue
        r2 = (pos9[q, 0] - cx) ** 2 + (pos9[q, 1] - cy) ** 2 + (pos9[q, 2] - cz) ** 2
        m = contact * math.exp(-0.5 * r2 / s2) * gain[t]
        vm += v9[q] * m
        mm += m * m
    out[1] = math.sqrt(used / curv) if used > 0 else np.nan
    if mm == 0:  # no taxel near the centre: no strength, no height
        out[0] = np.nan
        out[2] = np.nan
        out[3] = np.nan
        return
    s = vm / mm
    err = noise / math.sqrt(mm)
    out[0] = s
    out[2] = max(-decay * math.log(max(s, 1e-12)), 0.0)
    out[3] = decay * err / max(s, 1e-12)
