"""Taxels and the board: taxel grid indices (i, j) <-> frame cells (row, col).

Units: mm for taxel positions; counts in frames.

The scene's ``[board]`` maps taxel (i, j) to a frame cell: (a, b) = (j, i) when
``transpose`` else (i, j); row = offset_i + a, col = offset_j + b; then ``flip_i``
mirrors the frame rows (row -> rows - 1 - row, like the MuCa library versions that read
Tx in reverse) and ``flip_j`` the columns. By default frame[i, j] is taxel (i, j).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.scene import default_scene
from fruitcli.tables import read_table

BOARD_ROWS = default_scene().board.rows  # Tx lines of the FocalTech FT5316 (MuCa): frame rows
BOARD_COLS = default_scene().board.cols  # Rx lines: frame columns
FORMATS = ("ascii", "binary")  # the stock firmware's two frame formats (Muca_Raw, SendRawByte)

TAXEL_COLUMNS = ["id", "i", "j", "x_mm", "y_mm", "z_mm"]


@dataclass(frozen=True)
class Taxels:
    """Taxels in file order: ids, integer grid indices and rest positions (mm)."""

    ids: np.ndarray  # (T,) int
    i: np.ndarray  # (T,) int grid index
    j: np.ndarray  # (T,) int grid index
    xyz_mm: np.ndarray  # (T, 3) float

    def __len__(self) -> int:
        return int(self.ids.shape[0])


def load_taxels(path: str | os.PathLike) -> Taxels:
    """Read a taxel CSV (``#`` comments, header with at least id,i,j,x_mm,y_mm,z_mm)."""
    path = Path(path)
    cols = read_table(path, TAXEL_COLUMNS, error=FrameError)
    for name in ("id", "i", "j"):
        bad = np.nonzero(cols[name] != np.round(cols[name]))[0]
        if bad.size:
            raise FrameError(f"{path}: data row {bad[0] + 1}: column {name}: expected an "
                             f"integer, got {cols[name][bad[0]]}")
    i, j = cols["i"].astype(np.int64), cols["j"].astype(np.int64)
    bad = np.nonzero((i < 0) | (j < 0))[0]
    if bad.size:
        raise FrameError(f"{path}: data row {bad[0] + 1}: i, j: expected grid indices >= 0, "
                         f"got ({i[bad[0]]}, {j[bad[0]]})")
    ids = cols["id"].astype(np.int64)
    _, first = np.unique(ids, return_index=True)
    if first.size < ids.size:
        k = int(np.setdiff1d(np.arange(ids.size), first)[0])
        raise FrameError(f"{path}: data row {k + 1}: duplicate taxel id {ids[k]} (also on "
                         f"data row {int(np.nonzero(ids == ids[k])[0][0]) + 1})")
    key = i * (j.max() + 1) + j
    _, first, counts = np.unique(key, return_index=True, return_counts=True)
    if np.any(counts > 1):
        k = first[np.argmax(counts > 1)]
        raise FrameError(f"{path}: two taxels share grid index ({i[k]}, {j[k]})")
    xyz = np.stack([cols["x_mm"], cols["y_mm"], cols["z_mm"]], axis=1)
    return Taxels(ids, i, j, xyz)


def taxel_cells(taxels: Taxels, board, where: str = "taxels") -> tuple[np.ndarray, np.ndarray]:
    """Frame (rows, cols) of every taxel per the scene's ``[board]`` (a
    `fruitcli.scene.BoardSection`); outside -> FrameError."""
    a, b = (taxels.j, taxels.i) if board.transpose else (taxels.i, taxels.j)
    rows = board.offset_i + a
    cols = board.offset_j + b
    if board.flip_i:
        rows = board.rows - 1 - rows
    if board.flip_j:
        cols = board.cols - 1 - cols
    bad = np.nonzero((rows < 0) | (rows >= board.rows) | (cols < 0) | (cols >= board.cols))[0]
    if bad.size:
        k = bad[0]
        raise FrameError(f"{where}: taxel id {taxels.ids[k]} (i={taxels.i[k]}, j={taxels.j[k]}) "
                         f"maps to frame cell ({rows[k]}, {cols[k]}), outside the "
                         f"{board.rows} x {board.cols} frame")
    return rows.astype(np.int64), cols.astype(np.int64)


def default_board(rows: int = BOARD_ROWS, cols: int = BOARD_COLS):
    """The ``[board]`` defaults (a `fruitcli.scene.BoardSection`): frame[i, j] is taxel
    (i, j)."""
    return replace(default_scene().board, rows=rows, cols=cols)


def check_frame_shape(frames: np.ndarray, board, where: str) -> None:
    """Frames must be (N, rows, cols) as the board says."""
    want = (board.rows, board.cols)
    if tuple(frames.shape[1:]) != want:
        raise FrameError(f"{where}: frames of shape {tuple(frames.shape[1:])}, expected "
                         f"{want[0]} x {want[1]} per [board]")
