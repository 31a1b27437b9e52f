"""The MuCa ASCII line: one frame's counts comma-separated in the board's order (value k is
Tx k // C, Rx k % C), as the stock firmware prints it and `fruit record` logs it (with the
host time in seconds in front). Parsing and formatting are both here, once.
"""

from __future__ import annotations

import numpy as np


def looks_like_timestamp(field: str) -> bool:
    """A host timestamp as `fruit record` writes it: a finite number >= 0 with a decimal
    point or an exponent (``12.345``); a plain integer is a count, not a time."""
    f = field.strip()
    if not any(ch in f for ch in ".eE"):
        return False
    try:
        t = float(f)
    except ValueError:
        return False
    return bool(np.isfinite(t)) and t >= 0


def parse_line(line: str, n_cells: int) -> tuple[np.ndarray | None, float | None, str]:
    """Parse one log line into (counts (n_cells,), host time or None, problem).

    A line of n_cells + 1 fields is a host timestamp and the counts only when its first
    field looks like a timestamp (`looks_like_timestamp`); otherwise, when its last field
    is empty, the firmware's trailing comma is dropped; otherwise it is refused as
    shifted (every count would read its neighbour's). Returns (None, None, why) for a
    line to skip: wrong field count ("fields"), shifted ("shifted: ...") or a bad value
    ("value: ..."). Empty fields are 0 counts.
    """
    fields = line.strip().split(",")
    t = None
    if len(fields) == n_cells + 2 and not fields[-1].strip():
        fields = fields[:-1]  # timestamp, counts, trailing comma
    if len(fields) == n_cells + 1:
        if looks_like_timestamp(fields[0]):
            t = float(fields[0])
            fields = fields[1:]
        elif not fields[-1].strip():
            fields = fields[:-1]  # the firmware's trailing comma
        else:
            return (
                None,
                None,
                (
                    f"shifted: {n_cells + 1} fields, one more than the "
                    f"{n_cells} counts, and the first ({fields[0].strip()!r}) is "
                    "not a host timestamp (a number with a decimal point)"
                ),
            )
    elif len(fields) != n_cells:
        return None, None, "fields"
    if "" in fields:
        fields = [f if f.strip() else "0" for f in fields]
    try:
        counts = np.array(fields, dtype=np.int64)
    except (ValueError, OverflowError):
        for k, f in enumerate(fields):
            try:
                int(f)
            except ValueError:
                return None, None, f"value: field {k + 1}: expected an integer count, got {f!r}"
        big = next(k for k, f in enumerate(fields) if abs(int(f)) > 2**62)
        return None, None, f"value: field {big + 1}: count beyond the board's range (0 to 65535)"
    if counts.min() < 0:
        k = int(np.argmax(counts < 0))
        return None, None, f"value: field {k + 1}: negative count {counts[k]}"
    return counts, t, ""


def format_line(counts: np.ndarray, t_s: float | None = None, trailing_comma: bool = False) -> str:
    """One frame as a line, without its line end: the counts comma-separated in the
    board's order, after the host time `t_s` (s; `repr` keeps it exact) when given, with
    a trailing comma as some firmware sketches print it when `trailing_comma`."""
    body = ",".join(map(str, np.asarray(counts).ravel().tolist()))
    if trailing_comma:
        body += ","
    return body if t_s is None else f"{float(t_s)!r},{body}"
