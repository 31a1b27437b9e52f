"""Reading the project's tables: CSV (`#` comment lines, a header, numeric columns), npz
arrays, and the taxel CSV every stage shares.

Every error names the file, the row (1-based line number in the file) and the column.
"""

from __future__ import annotations

import csv
import math
import os
import zipfile
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fruitcli.errors import FruitError


def read_table(
    path: str | Path,
    required: list[str],
    numeric: list[str] | None = None,
    error: Callable[[str], Exception] = FruitError,
) -> dict[str, np.ndarray]:
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
    lines = [
        (n + 1, line)
        for n, line in enumerate(text.splitlines())
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not lines:
        raise error(f"{path}: empty file (expected a header with {', '.join(required)})")
    header_line, header = lines[0][0], next(csv.reader([lines[0][1]]))
    header = [h.strip() for h in header]
    repeated = sorted({h for h in header if header.count(h) > 1})
    if repeated:
        raise error(
            f"{path}: row {header_line}: column(s) {', '.join(repeated)} appear more "
            "than once in the header; expected each column once"
        )
    missing = [c for c in required if c not in header]
    if missing:
        raise error(
            f"{path}: row {header_line}: missing column(s) {', '.join(missing)} "
            f"(found {', '.join(header)})"
        )
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
                    raise error(
                        f"{path}: row {lineno}: column {h}: not a number: {value!r}"
                    ) from None
                if not math.isfinite(x):
                    raise error(f"{path}: row {lineno}: column {h}: not finite: {value!r}")
                cols[h].append(x)
            else:
                cols[h].append(value)
    return {
        h: (np.asarray(v, dtype=float) if h in numeric else np.asarray(v, dtype=object))
        for h, v in cols.items()
    }


def read_npz_arrays(
    path: str | Path,
    what: str,
    error: Callable[[str], Exception] = FruitError,
    missing_hint: str = "",
) -> dict:
    """All arrays of an npz file (`allow_pickle=False`) as a dict. A missing or unreadable
    file is one `error` line naming it; `what` says what it should be ("states .npz")."""
    path = Path(path)
    if not path.exists():
        raise error(f"{path}: file not found{missing_hint}")
    check_zip(path, what, error)
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except Exception as exc:
        why = (
            "it holds Python objects, not plain arrays" if "allow_pickle" in str(exc) else str(exc)
        )
        raise error(f"{path}: not a readable {what}: {why}") from None


def check_zip(path: str | Path, what: str, error: Callable[[str], Exception] = FruitError) -> None:
    """Read every member of the zip archive `path` (an .npz) and compare it with its stored
    CRC-32, as `np.load` does not: a flipped bit is one `error` line naming the file and
    member instead of wrong numbers."""
    try:
        with zipfile.ZipFile(path) as zf:
            bad = zf.testzip()
    except (OSError, EOFError, zipfile.BadZipFile, zlib.error, NotImplementedError) as exc:
        raise error(f"{path}: not a readable {what}: {exc}") from None
    if bad is not None:
        raise error(
            f"{path}: not a readable {what}: member {bad} fails its CRC check (the file is damaged)"
        )


TAXEL_COLUMNS = ["id", "i", "j", "x_mm", "y_mm", "z_mm"]


@dataclass(frozen=True)
class Taxels:
    """Taxels in file order: ids, integer grid indices and rest positions (mm)."""

    ids: np.ndarray  # (T,) int
    i: np.ndarray  # (T,) int grid index
    j: np.ndarray  # (T,) int grid index
    xyz_mm: np.ndarray  # (T, 3) float
    normals: np.ndarray | None = None  # (T, 3) outward unit normals, when the file has them

    def __len__(self) -> int:
        return int(self.ids.shape[0])


EXACT_INTEGER = 2**53
"""Largest integer a CSV column holds exactly (it is read as float64): ids and indices
beyond it would be rounded into each other, or not fit a 64-bit integer."""


def integer_column(
    path: Path, cols: dict, name: str, error: Callable[[str], Exception] = FruitError
) -> np.ndarray:
    """Column `name` of a `read_table` result as int64: every value an integer within
    +-EXACT_INTEGER, else one `error` naming the file, data row and column."""
    values = cols[name]
    bad = np.nonzero((values != np.round(values)) | (np.abs(values) > EXACT_INTEGER))[0]
    if bad.size:
        v = float(values[bad[0]])
        what = "an integer"
        if v == round(v):
            what = f"an integer within +-{EXACT_INTEGER} (2^53, exact in a CSV)"
        raise error(f"{path}: data row {bad[0] + 1}: column {name}: expected {what}, got {v!r}")
    return values.astype(np.int64)


def read_taxels(path: str | os.PathLike, error: Callable[[str], Exception] = FruitError) -> Taxels:
    """Read a taxel CSV (``#`` comments, header with at least id,i,j,x_mm,y_mm,z_mm, and
    optionally nx,ny,nz): integer grid indices >= 0, unique ids and grid indices. Every
    problem is one `error` naming the file and the data row."""
    path = Path(path)
    cols = read_table(path, TAXEL_COLUMNS, error=error)
    ids, i, j = (integer_column(path, cols, name, error) for name in ("id", "i", "j"))
    bad = np.nonzero((i < 0) | (j < 0))[0]
    if bad.size:
        raise error(
            f"{path}: data row {bad[0] + 1}: i, j: expected grid indices >= 0, "
            f"got ({i[bad[0]]}, {j[bad[0]]})"
        )
    _, first = np.unique(ids, return_index=True)
    if first.size < ids.size:
        k = int(np.setdiff1d(np.arange(ids.size), first)[0])
        raise error(
            f"{path}: data row {k + 1}: duplicate taxel id {ids[k]} (also on "
            f"data row {int(np.nonzero(ids == ids[k])[0][0]) + 1})"
        )
    key = i * (j.max() + 1) + j
    _, first, counts = np.unique(key, return_index=True, return_counts=True)
    if np.any(counts > 1):
        k = first[np.argmax(counts > 1)]
        raise error(f"{path}: two taxels share grid index ({i[k]}, {j[k]})")
    xyz = np.stack([cols["x_mm"], cols["y_mm"], cols["z_mm"]], axis=1)
    normals = None
    if all(c in cols for c in ("nx", "ny", "nz")):
        try:
            normals = np.c_[cols["nx"], cols["ny"], cols["nz"]].astype(float)
        except ValueError:
            raise error(f"{path}: columns nx, ny, nz: expected numbers") from None
    return Taxels(ids, i, j, xyz, normals)
