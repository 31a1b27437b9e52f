"""Mesh output that survives a float32 STL round trip (weld, then verify the reload)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def weld_float32(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Round vertices to float32, merge those a mesh reader merges on reload, drop faces
    that collapse and pairs of coincident faces (zero-volume fins left by the collapse).

    A reader (trimesh) merges vertices that agree to its merge tolerance (1e-8 mm), not
    only identical ones: two float32 vertices 2e-9 mm apart, as a boolean can leave where
    a tube ends on a wall, would otherwise reload as one and leave a collapsed face (the
    file then reads as two bodies, not watertight).
    """
    import trimesh

    v32 = np.asarray(vertices, dtype=np.float32)
    scale = 10.0 ** trimesh.util.decimal_to_digits(trimesh.tol.merge)
    key = np.round(v32.astype(np.float64) * scale).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    uniq = v32[first]
    f = inverse.reshape(-1)[np.asarray(faces)]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    sf = np.sort(f, axis=1).astype(np.int64)
    n = int(f.max()) + 1 if len(f) else 1
    _, inv, counts = np.unique(
        (sf[:, 0] * n + sf[:, 1]) * n + sf[:, 2], return_inverse=True, return_counts=True
    )
    return uniq.astype(float), f[counts[inv] % 2 == 1]


def write_stl(path: str | Path, vertices: np.ndarray, faces: np.ndarray) -> tuple[bool, int]:
    """Write a binary STL at `path` (welded first); returns how it reloads:
    (watertight and consistently wound, number of edge-connected bodies)."""
    import trimesh

    v, f = weld_float32(vertices, faces)
    trimesh.Trimesh(v, f, process=False).export(path, file_type="stl")
    back = trimesh.load_mesh(path, process=True)
    bodies = len(back.split(only_watertight=False)) if len(back.faces) else 0
    return bool(back.is_watertight and back.is_winding_consistent), bodies
