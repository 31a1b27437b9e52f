"""Compiled fast path (numba) for the ASCII frame lines of the live loop.

Units: counts. A line that is only decimal digits and commas (the stock Muca_Raw
firmware's form, possibly ending in ``\\r``), with exactly as many non-empty fields of at
most 18 digits as the frame has cells, reads as those integers: what `parse_line` makes
of it too (tests/test_sensing_io.py checks both on the same lines). Every other line
(trailing comma, host timestamp, spaces, signs, other characters, another field count)
goes to `parse_line`, which says why it is skipped.
"""

from __future__ import annotations

from numba import njit

MAX_DIGITS = 18  # 10**18 < 2**63: no int64 overflow


@njit(cache=True, nogil=True)
def plain_counts(line, out) -> bool:
    """Digits of `line` (uint8) into out (n,) int64; False when the line is not plain."""
    n = out.shape[0]
    end = line.shape[0]
    while end > 0 and line[end - 1] == 13:  # \r
        end -= 1
    field = 0
    value = 0
    digits = 0
    for at in range(end):
        c = line[at]
        if c == 44:  # ,
            if digits == 0 or field >= n - 1:
                return False
            out[field] = value
            field += 1
            value = 0
            digits = 0
        elif 48 <= c <= 57:
            digits += 1
            if digits > MAX_DIGITS:
                return False
            value = value * 10 + (c - 48)
        else:
            return False
    if digits == 0 or field != n - 1:
        return False
    out[field] = value
    return True
