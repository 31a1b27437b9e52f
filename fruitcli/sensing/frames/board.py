"""Taxels and the board: taxel grid indices (i, j) <-> frame cells (row, col).

Units: mm for taxel positions; counts in frames.

The scene's ``[board]`` maps taxel (i, j) to a frame cell: (a, b) = (j, i) when
``transpose`` else (i, j); row = offset_i + a, col = offset_j + b; then ``flip_i``
mirrors the frame rows (row -> rows - 1 - row, like the MuCa library versions that read
Tx in reverse) and ``flip_j`` the columns. By default frame[i, j] is taxel (i, j).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.scene import BoardSection, default_scene
from fruitcli.sensing.frames.formats import BOARD_COLS, BOARD_ROWS
from fruitcli.tables import Taxels

__all__ = ["BOARD_COLS", "BOARD_ROWS", "check_frame_shape", "default_board", "taxel_cells"]


def taxel_cells(
    taxels: Taxels, board: BoardSection, where: str = "taxels"
) -> tuple[np.ndarray, np.ndarray]:
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
        raise FrameError(
            f"{where}: taxel id {taxels.ids[k]} (i={taxels.i[k]}, j={taxels.j[k]}) "
            f"maps to frame cell ({rows[k]}, {cols[k]}), outside the "
            f"{board.rows} x {board.cols} frame"
        )
    return rows.astype(np.int64), cols.astype(np.int64)


def default_board(rows: int = BOARD_ROWS, cols: int = BOARD_COLS) -> BoardSection:
    """The ``[board]`` defaults (a `fruitcli.scene.BoardSection`): frame[i, j] is taxel
    (i, j)."""
    return replace(default_scene().board, rows=rows, cols=cols)


def check_frame_shape(frames: np.ndarray, board: BoardSection, where: str) -> None:
    """Frames must be (N, rows, cols) as the board says."""
    want = (board.rows, board.cols)
    if tuple(frames.shape[1:]) != want:
        raise FrameError(
            f"{where}: frames of shape {tuple(frames.shape[1:])}, expected "
            f"{want[0]} x {want[1]} per [board]"
        )
