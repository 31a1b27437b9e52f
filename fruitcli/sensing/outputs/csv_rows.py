"""CSV rows of numbers formatted in bulk, byte for byte as `fruitcli.fsutil.write_csv`
writes them (an int as ``str``, a float as ``"%.6f"``, a word picked from a list by an
int column as itself), by a compiled loop (`csv_kernel.format_into`).

A float x is written from the integer q = rint(|x| 1e6): its digits with the point six
places from the right, and a ``-`` when x's sign bit is set (Python writes ``-0.000000``
too). That equals Python's correctly rounded ``"%.6f"`` unless |x| 1e6 lies within its
own rounding error of a half (a tie or a near tie, which rint of the rounded product may
round the other way) or |x| is too large for q to be exact. Rows holding such a value
are formatted by Python instead; they are rare. NaN and the infinities are written as
Python writes them (``nan``, ``inf``, ``-inf``).
"""

from __future__ import annotations

import numpy as np


def _field(value: float | int, kind: str, words: tuple[str, ...]) -> str:
    if kind == "d":
        return str(int(value))
    if kind == "s":
        if not 0 <= int(value) < len(words):
            raise IndexError(f"word index {int(value)} outside the {len(words)} words")
        return words[int(value)]
    return f"{float(value):.6f}"


def _python_row(columns: list[np.ndarray], kinds: str, r: int, words: tuple[str, ...]) -> bytes:
    fields = [_field(c[r], k, words) for c, k in zip(columns, kinds, strict=True)]
    return (",".join(fields) + "\n").encode()


def format_rows(columns: list[np.ndarray], kinds: str, words: tuple[str, ...] = ()) -> bytes:
    """Rows ``a,b,...\\n`` of equal-length columns; `kinds` has ``d`` (int), ``f``
    (float, six decimals) or ``s`` (int column i written as ``words[i]``, ASCII) per
    column. Returns ASCII bytes; IndexError for a word index outside `words`."""
    from fruitcli.sensing.outputs.csv_kernel import MAX_FIELD, format_into

    if any(k not in "dfs" for k in kinds) or len(kinds) != len(columns):
        raise ValueError(f"column kinds: expected one 'd', 'f' or 's' per column, got {kinds!r}")
    n = int(np.asarray(columns[0]).shape[0]) if columns else 0
    if n == 0:
        return b""
    ints = np.zeros((n, max(len(kinds) - kinds.count("f"), 1)), np.int64)
    floats = np.zeros((n, max(kinds.count("f"), 1)))
    ii = ff = 0
    for col, kind in zip(columns, kinds, strict=True):
        if kind in "ds":
            ints[:, ii] = col
            ii += 1
        else:
            floats[:, ff] = col
            ff += 1
    code = np.array(["dfs".index(k) for k in kinds], np.int64)
    encoded = [w.encode("ascii") for w in words]
    longest = max([len(w) for w in encoded], default=0)
    table = np.zeros((len(encoded), max(longest, 1)), np.uint8)
    for r, w in enumerate(encoded):
        table[r, : len(w)] = np.frombuffer(w, np.uint8)
    lengths = np.array([len(w) for w in encoded], np.int64)
    field = max(MAX_FIELD, longest) + 1
    out = np.empty(n * len(kinds) * field, np.uint8)
    ends = np.empty(n, np.int64)
    bad = np.zeros(n, np.bool_)
    size = format_into(ints, floats, code, table, lengths, out, ends, bad)
    flat = out[:size].tobytes()
    if not bad.any():
        return flat
    pieces, start = [], 0
    for row in np.flatnonzero(bad):
        pieces += [flat[start : ends[row]], _python_row(columns, kinds, int(row), words)]
        start = int(ends[row])
    pieces.append(flat[start:])
    return b"".join(pieces)
