"""touches.csv written chunk by chunk: the rows of each chunk's touches formatted in bulk.

Units: s, mm, counts. Columns: frame, t_s, touch, i, j, x_mm, y_mm, z_mm, peak (counts),
height_mm (above the surface) and height_err_mm (its 1-sigma uncertainty), strength
(1: contact), size_mm (footprint sigma) and kind (touch or hover, written as its name);
with the model method (`MODEL_HEADER`), also pos_err_mm (the point's 1-sigma radius),
residual (the fit's RMS weighted residual, 1: at the noise) and fit (model, or n9 where
the fit failed a test and the N9 point was kept; `fruitcli.sensing.detection.model_fit`).
The numbers' bytes are those `fruitcli.fsutil.write_csv` writes for the same rows
(``# `` comment lines, the header, ints as ``str``, floats as ``"%.6f"``); the file
appears only when complete (`atomic_path`), so an error half way leaves nothing behind.
"""

from __future__ import annotations

import contextlib
import csv
import io
import os
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.fsutil import atomic_path
from fruitcli.sensing.detection.model_fit import FIT_NAMES
from fruitcli.sensing.detection.touch_table import KIND_NAMES, TouchTable
from fruitcli.sensing.outputs.csv_rows import format_rows

if TYPE_CHECKING:
    from _typeshed import SupportsWrite

TOUCH_HEADER = [
    "frame",
    "t_s",
    "touch",
    "i",
    "j",
    "x_mm",
    "y_mm",
    "z_mm",
    "peak",
    "height_mm",
    "height_err_mm",
    "strength",
    "size_mm",
    "kind",
]
MODEL_HEADER = ["pos_err_mm", "residual", "fit"]
_KINDS = "dfdffffffffffs"  # kind: written as its name
_WORDS = KIND_NAMES + tuple(f"{name or 'none'}" for name in FIT_NAMES)  # kind, then fit


def touch_bytes(table: TouchTable, t_s: np.ndarray, model: bool = False) -> bytes:
    """The data rows of touches.csv for `table`; `t_s` (N,) s of every frame; `model`:
    with the model method's columns."""
    if len(table) == 0:
        return b""
    xyz = table.xyz_mm
    extra: list[np.ndarray] = []
    if model:
        extra = [table.pos_err_mm, table.residual, table.fit.astype(np.int64) + len(KIND_NAMES)]
    return format_rows(
        [
            table.frame,
            t_s[table.frame],
            table.touch,
            table.i,
            table.j,
            xyz[:, 0],
            xyz[:, 1],
            xyz[:, 2],
            table.peak,
            table.height_mm,
            table.height_err_mm,
            table.strength,
            table.size_mm,
            table.kind,
            *extra,
        ],
        _KINDS + ("ffs" if model else ""),
        _WORDS,
    )


class _Rows:
    def __init__(self, fh: SupportsWrite[bytes]):
        self._fh, self.rows = fh, 0

    def write(self, data: bytes, rows: int) -> None:
        """Append `rows` rows from `touch_bytes`."""
        self._fh.write(data)
        self.rows += rows


@contextlib.contextmanager
def touch_csv(
    path: str | os.PathLike, comments: Sequence[str] = (), model: bool = False
) -> Iterator[_Rows]:
    """``with touch_csv(path, comments) as out: out.write(touch_bytes(table, t_s),
    len(table))`` per chunk; `model`: with the model method's columns."""
    head = io.StringIO()
    for line in comments:
        head.write(f"# {line}\n")
    csv.writer(head, lineterminator="\n").writerow(TOUCH_HEADER + (MODEL_HEADER if model else []))
    with atomic_path(path) as tmp, open(tmp, "w") as fh:  # text, as write_csv writes
        fh.write(head.getvalue())
        fh.flush()
        yield _Rows(fh.buffer)
