"""Reading the project's tables: CSV (`#` comment lines, a header, numeric columns) and
npz arrays.

Every error names the file, the row (1-based line number in the file) and the column.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from fruitcli.errors import FruitError


def read_table(path: str | Path, required: list[str], numeric: list[str] | None = None,
               error=FruitError) -> dict[str, np.ndarray]:
    """Read a CSV into columns. `required` columns must exist; `numeric` ones (default:
    all required) must be finite numbers. Returns {column: (n,) array} (str for others)."""
    path = Path(path)
    numeric = required if numeric is None else numeric
    if not path.exists():
        raise error(f"{path}: file not found")
    try:
        text = path.read_text(encoding="utf-8-sig")  # a spreadsheet's byte-order mark
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{path}: cannot read as text: {exc}") from None
    lines = [(n + 1, line) for n, line in enumerate(text.splitlines())
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise error(f"{path}: empty file (expected a header with {', '.join(required)})")
    header_line, header = lines[0][0], next(csv.reader([lines[0][1]]))
    header = [h.strip() for h in header]
    missing = [c for c in required if c not in header]
    if missing:
        raise error(f"{path}: row {header_line}: missing column(s) {', '.join(missing)} "
                    f"(found {', '.join(header)})")
    if len(lines) == 1:
        raise error(f"{path}: no data rows after the header")
    cols: dict[str, list] = {h: [] for h in header}
    for lineno, line in lines[1:]:
        row = next(csv.reader([line]))
        if len(row) != len(header):
            raise error(f"{path}: row {lineno}: expected {len(header)} fields, got {len(row)}")
        for h, value in zip(header, row, strict=True):
            value = value.strip()
            if h in numeric:
                try:
                    x = float(value)
                except ValueError:
                    raise error(f"{path}: row {lineno}: column {h}: not a number: "
                                f"{value!r}") from None
                if not math.isfinite(x):
                    raise error(f"{path}: row {lineno}: column {h}: not finite: {value!r}")
                cols[h].append(x)
            else:
                cols[h].append(value)
    return {h: (np.asarray(v, dtype=float) if h in numeric else np.asarray(v, dtype=object))
            for h, v in cols.items()}


def read_npz_arrays(path: str | Path, what: str, error=FruitError, missing_hint: str = "") -> dict:
    """All arrays of an npz file (`allow_pickle=False`) as a dict. A missing or unreadable
    file is one `error` line naming it; `what` says what it should be ("states .npz")."""
    path = Path(path)
    if not path.exists():
        raise error(f"{path}: file not found{missing_hint}")
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except Exception as exc:  # noqa: BLE001 - any unreadable npz is one error line
        why = ("it holds Python objects, not plain arrays" if "allow_pickle" in str(exc)
               else str(exc))
        raise error(f"{path}: not a readable {what}: {why}") from None
