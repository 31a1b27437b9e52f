"""The board's frame size and the stock MuCa firmware's frame formats, one table
(``[board].format``, ``--format``).

The scene schema's defaults and choices, the command line's choices and the readers
(`muca`) read it. This module imports nothing, so the scene schema can read it.
"""

from __future__ import annotations

from dataclasses import dataclass

BOARD_ROWS = 21
"""Tx lines of the FocalTech FT5316 (MuCa): frame rows, the ``[board].rows`` default."""
BOARD_COLS = 12
"""Rx lines: frame columns, the ``[board].cols`` default."""


@dataclass(frozen=True)
class BoardFormat:
    """A frame format of the stock firmware: `name` and what sends it."""

    name: str
    doc: str


BOARD_FORMATS: dict[str, BoardFormat] = {
    f.name: f
    for f in (
        BoardFormat("ascii", "Muca_Raw's ASCII lines"),
        BoardFormat("binary", "SendRawByte's binary packets"),
    )
}
"""The stock MuCa firmware's two frame formats (`fruitcli.sensing.frames.muca`); readers
also take "auto"."""
