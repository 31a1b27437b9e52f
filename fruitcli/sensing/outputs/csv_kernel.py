"""Compiled loop (numba) writing CSV rows of numbers as Python's ``str(int)`` and
``"%.6f"`` write them (``nan``, ``inf``, ``-inf`` for the non-finite), and words picked
from a list by an int column; see `fruitcli.sensing.outputs.csv_rows` for the rule and
its exceptions. Releases the GIL; compiled (or loaded from numba's disk cache) on first
use."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

MAX_EXACT = 2.0**52 / 1e6  # |x| below this: |x| 1e6 < 2**52, so rint is an exact integer
REL_ERR = 2.0**-50  # bound on the relative error of fl(|x| 1e6) (2**-53), with margin
MAX_FIELD = 22  # bytes of one number at most: "-" + 20 digits, or "-" + 10 + "." + 6
_NAN = np.frombuffer(b"nan", np.uint8)  # as Python writes NaN of either sign
_INF = np.frombuffer(b"inf", np.uint8)


@njit(cache=True, nogil=True)
def _put_uint(out, at, u):
    """Decimal digits of u (uint64) at out[at:]; returns the position after them."""
    width = 1
    rest = u // np.uint64(10)
    while rest > 0:
        width += 1
        rest //= np.uint64(10)
    for m in range(width - 1, -1, -1):
        out[at + m] = 48 + u % np.uint64(10)
        u //= np.uint64(10)
    return at + width


@njit(cache=True, nogil=True)
def _put_text(out, at, text, size):
    """Bytes text[:size] at out[at:]; returns the position after them."""
    for m in range(size):
        out[at + m] = text[m]
    return at + size


@njit(cache=True, nogil=True)
def format_into(ints, floats, kinds, words, word_len, out, ends, bad) -> int:
    """Rows r of columns given by `kinds` (0: next column of ints (n, a) int64, 1: next of
    floats (n, b) float64, 2: next column of ints as an index into words (W, L) uint8 of
    word_len (W,) bytes) written at out; ends[r] = position after row r. A row with a
    float Python must format (see csv_rows) or a word index out of range is left out and
    marked in bad[r]. Returns the number of bytes written."""
    n = ends.shape[0]
    at = 0
    for r in range(n):
        start = at
        ii = 0
        ff = 0
        ok = True
        for c in range(kinds.shape[0]):
            if c > 0:
                out[at] = 44  # ,
                at += 1
            if kinds[c] == 2:
                w = ints[r, ii]
                ii += 1
                if w < 0 or w >= word_len.shape[0]:
                    ok = False
                    break
                at = _put_text(out, at, words[w], word_len[w])
            elif kinds[c] == 0:
                v = ints[r, ii]
                ii += 1
                if v < 0:
                    out[at] = 45  # -
                    at += 1
                    at = _put_uint(out, at, np.uint64(-(v + 1)) + np.uint64(1))
                else:
                    at = _put_uint(out, at, np.uint64(v))
            else:
                x = floats[r, ff]
                ff += 1
                a = abs(x)
                if math.isnan(x):
                    at = _put_text(out, at, _NAN, 3)
                    continue
                if math.isinf(x):
                    if x < 0:
                        out[at] = 45
                        at += 1
                    at = _put_text(out, at, _INF, 3)
                    continue
                if not a < MAX_EXACT:
                    ok = False
                    break
                y = a * 1e6
                q = np.rint(y)
                if abs(abs(y - q) - 0.5) <= y * REL_ERR:
                    ok = False
                    break
                if math.copysign(1.0, x) < 0:
                    out[at] = 45
                    at += 1
                qi = np.uint64(q)
                whole = qi // np.uint64(1_000_000)
                frac = qi - whole * np.uint64(1_000_000)
                at = _put_uint(out, at, whole)
                out[at] = 46  # .
                for m in range(6, 0, -1):
                    out[at + m] = 48 + frac % np.uint64(10)
                    frac //= np.uint64(10)
                at += 7
        if ok:
            out[at] = 10  # newline
            at += 1
        else:
            at = start
            bad[r] = True
        ends[r] = at
    return at
