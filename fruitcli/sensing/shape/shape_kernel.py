"""Compiled touch shapes (numba) for the Gaussian skin's gap law: `touch_shape` per touch
in one loop, for the live loop's per-frame budget.

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
def gap_law_shapes(v9, tax9, pos9, xyz, contact, decay, sigma, noise, gain, min_counts, out):
    """out[k] = (strength, size_mm, height_mm, height_err_mm) of touch k from its N9
    activations v9 (n, 9), taxels tax9 (n, 9) (-1: none), positions pos9 (n, 9, 3),
    reported point xyz (n, 3); gain (T,) the model's taxel gains (ones: none)."""
    for k in range(v9.shape[0]):
        c = np.empty(3)
        for d in range(3):
            c[d] = xyz[k, d]
        curv = 0.0
        used = 0
        for axis in range(2):
            lo = _LO[axis]
            hi = _HI[axis]
            a2 = 0.0
            b2 = 0.0
            for d in range(3):
                a2 += (pos9[k, 4, d] - pos9[k, lo, d]) ** 2
                b2 += (pos9[k, hi, d] - pos9[k, 4, d]) ** 2
            a = math.sqrt(a2)
            b = math.sqrt(b2)
            has_lo = v9[k, lo] > min_counts and a > 0
            has_hi = v9[k, hi] > min_counts and b > 0
            if a == 0:
                a = 1.0
            if b == 0:
                b = 1.0
            l0 = math.log(max(v9[k, 4], min_counts))
            llo = math.log(max(v9[k, lo], min_counts))
            lhi = math.log(max(v9[k, hi], min_counts))
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
            u = np.empty(3)
            norm = 0.0
            for d in range(3):
                u[d] = ((pos9[k, 4, d] - pos9[k, lo, d]) + (pos9[k, hi, d] - pos9[k, 4, d])) / (
                    a + b
                )
                norm += u[d] * u[d]
            norm = max(math.sqrt(norm), 1e-12)
            along = delta
            for d in range(3):
                u[d] /= norm
                along += (pos9[k, 4, d] - c[d]) * u[d]
            for d in range(3):
                c[d] += along * u[d]
        vm = 0.0
        mm = 0.0
        for q in range(9):
            t = tax9[k, q]
            if t < 0:
                continue
            r2 = 0.0
            for d in range(3):
                r2 += (pos9[k, q, d] - c[d]) ** 2
            m = contact * math.exp(-0.5 * r2 / (sigma * sigma)) * gain[t]
            vm += v9[k, q] * m
            mm += m * m
        s = vm / mm
        err = noise / math.sqrt(mm)
        out[k, 0] = s
        out[k, 1] = math.sqrt(used / curv) if used > 0 else np.nan
        out[k, 2] = max(-decay * math.log(max(s, 1e-12)), 0.0)
        out[k, 3] = decay * err / max(s, 1e-12)
