"""CSV rows of numbers formatted in bulk, byte for byte as `fruitcli.fsutil.write_csv`
writes them (an int as ``str``, a float as ``"%.6f"``), by a compiled loop
(`csv_kernel.format_into`).

A float x is written from the integer q = rint(|x| 1e6): its digits with the point six
places from the right, and a ``-`` when x's sign bit is set (Python writes ``-0.000000``
too). That equals Python's correctly rounded ``"%.6f"`` unless |x| 1e6 lies within its
own rounding error of a half (a tie or a near tie, which rint of the rounded product may
round the other way) or |x| is too large for q to be exact. Rows holding such a value,
a NaN or an infinity are formatted by Python instead; they are rare.
"""

from __future__ import annotations

import numpy as np


def _python_row(columns: list[np.ndarray], kinds: str, r: int) -> bytes:
    fields = [
        str(int(c[r])) if k == "d" else f"{float(c[r]):.6f}"
        for c, k in zip(columns, kinds, strict=True)
    ]
    return (",".join(fields) + "\n").encode()


def format_rows(columns: list[np.ndarray], kinds: str) -> bytes:
    """Rows ``a,b,...\\n`` of equal-length columns; `kinds` has ``d`` (int) or ``f``
    (float, six decimals) per column. Returns ASCII bytes."""
    from fruitcli.sensing.outputs.csv_kernel import MAX_FIELD, format_into

    if any(k not in "df" for k in kinds) or len(kinds) != len(columns):
        raise ValueError(f"column kinds: expected one 'd' or 'f' per column, got {kinds!r}")
    n = int(np.asarray(columns[0]).shape[0]) if columns else 0
    if n == 0:
        return b""
    ints = np.zeros((n, max(kinds.count("d"), 1)), np.int64)
    floats = np.zeros((n, max(kinds.count("f"), 1)))
    ii = ff = 0
    for col, kind in zip(columns, kinds, strict=True):
        if kind == "d":
            ints[:, ii] = col
            ii += 1
        else:
            floats[:, ff] = col
            ff += 1
    code = np.array([0 if k == "d" else 1 for k in kinds], np.int64)
    out = np.empty(n * len(kinds) * (MAX_FIELD + 1), np.uint8)
    ends = np.empty(n, np.int64)
    bad = np.zeros(n, np.bool_)
    size = format_into(ints, floats, code, out, ends, bad)
    flat = out[:size].tobytes()
    if not bad.any():
        return flat
    pieces, start = [], 0
    for r in np.flatnonzero(bad):
        pieces += [flat[start : ends[r]], _python_row(columns, kinds, int(r))]
        start = int(ends[r])
    pieces.append(flat[start:])
    return b"".join(pieces)
