"""Pressure tables for `fruit simulate --pressures`: a CSV with one row per state and
one column `<chamber>_kpa` per chamber (kPa), `#` comment lines allowed (units,
provenance), as the project's other CSVs (`fruitcli.tables`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FruitError
from fruitcli.fsutil import write_csv
from fruitcli.tables import read_table

if TYPE_CHECKING:
    from numpy.typing import ArrayLike


def column(chamber: str) -> str:
    return f"{chamber}_kpa"


def read_pressures(path: str | Path, chambers: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(kPa (S, K) in `chambers` order, file line number of each row (S,)). One
    FruitError line naming the file, and the row or column, for a missing or extra
    column, a value that is not a finite number, or no rows."""
    path = Path(path)
    want = [column(c) for c in chambers]
    table = _read(path, want)
    kpa = np.stack([table[c] for c in want], axis=1) if want else np.zeros((0, 0))
    return kpa, table["__line__"]


def _read(path: Path, want: list[str]) -> dict:
    table = read_table(path, want, error=FruitError)
    text_lines = _data_lines(path)
    extra = [h for h in table if h not in want]
    if extra:
        raise FruitError(
            f"{path}: row {text_lines[0][0]}: unexpected column(s) "
            f"{', '.join(extra)}: expected one column per chamber: "
            f"{', '.join(want)} (kPa)"
        )
    table["__line__"] = np.array([n for n, _ in text_lines[1:]], np.int64)
    return table


def _data_lines(path: Path) -> list[tuple[int, str]]:
    """(line number, text) of the non-comment, non-blank lines ([] if unreadable: the
    table reader then names the problem)."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError):
        return []
    return [
        (n + 1, line)
        for n, line in enumerate(text.splitlines())
        if line.strip() and not line.lstrip().startswith("#")
    ]


def write_pressures(
    path: str | Path, chambers: list[str], kpa: ArrayLike, comment: str = ""
) -> None:
    """Write (S, K) kPa as a pressure table, atomically."""
    rows = [
        [repr(float(v)) for v in row]  # repr: read back exactly
        for row in np.asarray(kpa, float).reshape(-1, len(chambers))
    ]
    write_csv(
        path,
        [column(c) for c in chambers],
        rows,
        comments=[comment or "chamber pressures, kPa, one row per state"],
    )
