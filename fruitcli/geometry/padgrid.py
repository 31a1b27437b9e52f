"""Taxels of a flat pad: a regular nx x ny grid centred on the pad's top face (z = thickness)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fruitcli.errors import SceneError
from fruitcli.fsutil import write_csv

TAXEL_HEADER = ["id", "i", "j", "x_mm", "y_mm", "z_mm", "nx", "ny", "nz"]


def pad_taxels(pad_size_mm, count, spacing_x_mm: float, spacing_y_mm: float) -> np.ndarray:
    """Rows (id, i, j, x, y, z, nx, ny, nz) in mm, i along x, j along y, normal +z."""
    nx, ny = (int(c) for c in count)
    if nx < 1 or ny < 1:
        raise SceneError(f"[grid].count: expected two positive integers, got {count}")
    sx, sy, t = pad_size_mm
    half_x, half_y = (nx - 1) * spacing_x_mm / 2, (ny - 1) * spacing_y_mm / 2
    if half_x > sx / 2 or half_y > sy / 2:
        raise SceneError(f"[grid]: {nx} x {ny} taxels do not fit on a {sx} x {sy} mm pad")
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    i, j = i.ravel(), j.ravel()
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


def write_pad_taxels(path: Path, pad_size_mm, count, spacing_x_mm, spacing_y_mm) -> int:
    rows = pad_taxels(pad_size_mm, count, spacing_x_mm, spacing_y_mm)
    out = [[int(r[0]), int(r[1]), int(r[2]), *map(float, r[3:])] for r in rows]
    write_csv(
        path,
        TAXEL_HEADER,
        out,
        comments=["taxels of a flat pad; positions in mm, unit outward normals"],
    )
    return len(out)
