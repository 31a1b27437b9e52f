"""CSV rows of numbers formatted in bulk, byte for byte as `fruitcli.fsutil.write_csv`
writes them (an int as ``str``, a float as ``"%.6f"``), at numpy speed.

A float x is written from the integer q = rint(|x| 1e6): its digits with the point six
places from the right, and a ``-`` when x's sign bit is set (Python writes ``-0.000000``
too). That equals Python's correctly rounded ``"%.6f"`` unless |x| 1e6 lies within its
own rounding error of a half (a tie or a near tie, which rint of the rounded product may
round the other way) or |x| is too large for q to be exact. Rows holding such a value,
a NaN or an infinity are formatted by Python instead; they are rare.

The rows are first laid out as fixed-width records (n, W) bytes, each number right-
aligned in its field with 0 bytes before it; a float's ``.dddddd`` and the separator
after it are one 8-byte word written at once. Dropping the 0 bytes gives the text.
"""

from __future__ import annotations

import numpy as np

_MAX_EXACT = 2.0**52 / 1e6  # |x| below this: |x| 1e6 < 2**52, so rint is an exact integer
_REL_ERR = 2.0**-50  # bound on the relative error of fl(|x| 1e6) (2**-53), with margin
_ZERO, _MINUS, _POINT, _COMMA, _NEWLINE = (ord(c) for c in "0-.,\n")
# "00" .. "99" as little-endian 16-bit words (first digit in the low byte)
_PAIRS = np.array([(_ZERO + k // 10) | (_ZERO + k % 10) << 8 for k in range(100)], np.int64)


def _width(top: int) -> int:
    return len(str(int(top)))


def _column(table: np.ndarray, at: int, dtype) -> np.ndarray:
    """The (n,) view of `dtype` starting at byte `at` of every record of `table` (n, W)."""
    return np.ndarray(table.shape[:1], dtype=dtype, buffer=table, offset=at,
                      strides=table.strides[:1])


def _put_digits(table: np.ndarray, at: int, width: int, q: np.ndarray) -> None:
    """Decimal digits of non-negative `q` (n,) right-aligned in bytes at .. at + width - 1;
    places above a number's first digit stay 0."""
    rest = q
    for place in range(width):
        nxt = rest // 10  # numpy divides by a constant fast; divmod does not
        d = rest - nxt * 10
        d += _ZERO
        if place:
            d *= q >= 10**place
        table[:, at + width - 1 - place] = d
        rest = nxt


def _fraction_word(frac: np.ndarray, end: int) -> np.ndarray:
    """".dddddd" and the byte `end` after it as one little-endian 8-byte word per value;
    `frac` (n,) int64 in 0 .. 999999."""
    a = frac // 10_000
    rest = frac - a * 10_000
    b = rest // 100
    c = rest - b * 100
    word = _PAIRS[a] << 8
    word |= _PAIRS[b] << 24
    word |= _PAIRS[c] << 40
    word |= _POINT | end << 56
    return word


def _prepare(columns: list[np.ndarray], kinds: str):
    """Per column: (kind, negative (n,), integer part (n,), fraction or None, digits);
    and the rows Python must format."""
    fields = []
    n = columns[0].shape[0]
    unsafe = np.zeros(n, bool)
    for col, kind in zip(columns, kinds, strict=True):
        if kind == "d":
            v = np.asarray(col, dtype=np.int64)
            mag = np.abs(v)
            fields.append((kind, v < 0, mag, None, _width(mag.max())))
        elif kind == "f":
            x = np.asarray(col, dtype=np.float64)
            a = np.abs(x)
            with np.errstate(invalid="ignore"):
                bad = ~(a < _MAX_EXACT)  # also NaN
                if bad.any():
                    a = np.where(bad, 0.0, a)
                y = a * 1e6
                q = np.rint(y)
                bad |= np.abs(np.abs(y - q) - 0.5) <= y * _REL_ERR
            unsafe |= bad
            q = q.astype(np.int64)
            whole = q // 1_000_000
            fields.append((kind, np.signbit(x), whole, q - whole * 1_000_000,
                           _width(whole.max())))
        else:
            raise ValueError(f"column kind: expected 'd' or 'f', got {kind!r}")
    return fields, unsafe


def _python_row(columns: list[np.ndarray], kinds: str, r: int) -> bytes:
    fields = [str(int(c[r])) if k == "d" else f"{float(c[r]):.6f}"
              for c, k in zip(columns, kinds, strict=True)]
    return (",".join(fields) + "\n").encode()


def format_rows(columns: list[np.ndarray], kinds: str) -> bytes:
    """Rows ``a,b,...\\n`` of equal-length columns; `kinds` has ``d`` (int) or ``f``
    (float, six decimals) per column. Returns ASCII bytes."""
    n = int(np.asarray(columns[0]).shape[0]) if columns else 0
    if n == 0:
        return b""
    fields, unsafe = _prepare(columns, kinds)
    width = sum(1 + w + (8 if kind == "f" else 1) for kind, *_, w in fields)
    table = np.zeros((n, width), np.uint8)
    at = 0
    for k, (kind, negative, whole, frac, w) in enumerate(fields):
        end = _NEWLINE if k == len(fields) - 1 else _COMMA
        if negative.any():
            table[:, at] = negative * np.uint8(_MINUS)
        _put_digits(table, at + 1, w, whole)
        at += 1 + w
        if kind == "f":
            _column(table, at, "<i8")[:] = _fraction_word(frac, end)
            at += 8
        else:
            table[:, at] = end
            at += 1
    if not unsafe.any():
        return table[table != 0].tobytes()
    table[unsafe] = 0
    flat = table[table != 0].tobytes()
    ends = np.cumsum(np.count_nonzero(table, axis=1))
    out, start = [], 0
    for r in np.flatnonzero(unsafe):
        out += [flat[start:ends[r]], _python_row(columns, kinds, int(r))]
        start = int(ends[r])
    out.append(flat[start:])
    return b"".join(out)
