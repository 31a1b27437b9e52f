"""Taxels of a flat pad: a regular nx x ny grid centred on the pad's top face (z = thickness),
and its yarn tracks: the grid lines through the taxels, edge to edge on the top face
(the sections x = const and y = const that make-tracks cuts on an artist's surface)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fruitcli.errors import SceneError
from fruitcli.fsutil import write_csv

TAXEL_HEADER = ["id", "i", "j", "x_mm", "y_mm", "z_mm", "nx", "ny", "nz"]
TRACK_HEADER = ["track", "axis", "index", "point", "x_mm", "y_mm", "z_mm"]
TRACK_STEP_MM = 0.5
"""Largest distance between two points of a track (mm)."""


ROW_BYTES = 400.0
"""Memory one taxel or track row takes while it is built and written (bytes: a Python list
of nine numbers and its array row)."""


def pad_rows(pad_size_mm: Sequence[float], count: Sequence[int]) -> tuple[int, int]:
    """Rows of a pad's taxels.csv (nx * ny) and tracks.csv (points of its grid lines)."""
    nx, ny = (int(c) for c in count)
    sx, sy, _ = pad_size_mm
    points = nx * (math.ceil(sy / TRACK_STEP_MM) + 1) + ny * (math.ceil(sx / TRACK_STEP_MM) + 1)
    return nx * ny, points


def check_pad_size(pad_size_mm: Sequence[float], count: Sequence[int], where: str) -> None:
    """Refuse (SceneError naming `where`) a grid whose rows would not fit in memory."""
    from fruitcli.memory import require

    taxels, points = pad_rows(pad_size_mm, count)
    require(
        (taxels + points) * ROW_BYTES,
        f"{where}: [grid].count = {list(count)} on pad_size_mm = {list(pad_size_mm)} "
        f"({taxels:,} taxels, {points:,} track points)",
        SceneError,
    )


def pad_taxels(
    pad_size_mm: Sequence[float], count: Sequence[int], spacing_x_mm: float, spacing_y_mm: float
) -> np.ndarray:
    """Rows (id, i, j, x, y, z, nx, ny, nz) in mm, i along x, j along y, normal +z."""
    nx, ny = (int(c) for c in count)
    if nx < 1 or ny < 1:
        raise SceneError(f"[grid].count: expected two positive integers, got {count}")
    sx, sy, t = pad_size_mm
    half_x, half_y = (nx - 1) * spacing_x_mm / 2, (ny - 1) * spacing_y_mm / 2
    if half_x > sx / 2 or half_y > sy / 2:
        raise SceneError(f"[grid]: {nx} x {ny} taxels do not fit on a {sx} x {sy} mm pad")
    i, j = (a.ravel() for a in np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij"))
    x = i * spacing_x_mm - half_x
    y = j * spacing_y_mm - half_y
    rows = np.column_stack(
        [
            np.arange(len(i)),
            i,
            j,
            x,
            y,
            np.full_like(x, t),
            np.zeros_like(x),
            np.zeros_like(x),
            np.ones_like(x),
        ]
    )
    return rows


def write_pad_taxels(
    path: Path,
    pad_size_mm: Sequence[float],
    count: Sequence[int],
    spacing_x_mm: float,
    spacing_y_mm: float,
) -> int:
    rows = pad_taxels(pad_size_mm, count, spacing_x_mm, spacing_y_mm)
    out = [[int(r[0]), int(r[1]), int(r[2]), *map(float, r[3:])] for r in rows]
    write_csv(
        path,
        TAXEL_HEADER,
        out,
        comments=["taxels of a flat pad; positions in mm, unit outward normals"],
    )
    return len(out)


def pad_tracks(
    pad_size_mm: Sequence[float], count: Sequence[int], spacing_x_mm: float, spacing_y_mm: float
) -> list[list]:
    """Rows (track, axis, index, point, x, y, z) mm of the pad's grid lines on its top
    face: axis x, the line x = const through taxels i = index (along y); axis y, the line
    y = const through taxels j = index (along x); each from edge to edge, points at most
    TRACK_STEP_MM apart."""
    rows = pad_taxels(pad_size_mm, count, spacing_x_mm, spacing_y_mm)
    sx, sy, t = pad_size_mm
    out, track = [], 0
    for axis, col, along in (("x", 1, sy), ("y", 2, sx)):
        for index in np.unique(rows[:, col]).astype(int):
            at = rows[rows[:, col] == index][0, 3 if axis == "x" else 4]
            s = np.linspace(-along / 2, along / 2, int(np.ceil(along / TRACK_STEP_MM)) + 1)
            for n, v in enumerate(s):
                x, y = (at, v) if axis == "x" else (v, at)
                out.append([track, axis, int(index), n, float(x), float(y), float(t)])
            track += 1
    return out


def write_pad_tracks(
    path: Path,
    pad_size_mm: Sequence[float],
    count: Sequence[int],
    spacing_x_mm: float,
    spacing_y_mm: float,
) -> int:
    """tracks.csv of the pad's grid lines (as make-tracks writes); -> number of tracks."""
    rows = pad_tracks(pad_size_mm, count, spacing_x_mm, spacing_y_mm)
    write_csv(
        path,
        TRACK_HEADER,
        rows,
        comments=[
            "yarn track centre lines of a flat pad: its grid lines on the top face (mm)",
            "track: line number; axis x: the line x = const of grid index i (index), "
            "axis y: y = const of index j; point: order along the line",
        ],
    )
    return rows[-1][0] + 1
