"""Mesh output that survives a float32 STL round trip (weld, then verify the reload)."""

from __future__ import annotations

import numpy as np


def weld_float32(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Round vertices to float32, merge those that coincide, drop faces that collapse and
    pairs of coincident faces (zero-volume fins left by the collapse)."""
    v32 = np.asarray(vertices, dtype=np.float32)
    uniq, inverse = np.unique(v32, axis=0, return_inverse=True)
    f = inverse.reshape(-1)[np.asarray(faces)]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    sf = np.sort(f, axis=1).astype(np.int64)
    n = int(f.max()) + 1 if len(f) else 1
    _, inv, counts = np.unique((sf[:, 0] * n + sf[:, 1]) * n + sf[:, 2], return_inverse=True,
                               return_counts=True)
    return uniq.astype(float), f[counts[inv] % 2 == 1]


def write_stl(path, vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Write a binary STL at `path` (welded first); True if it reloads watertight."""
    import trimesh

    v, f = weld_float32(vertices, faces)
    trimesh.Trimesh(v, f, process=False).export(path, file_type="stl")
    back = trimesh.load_mesh(path, process=True)
    return bool(back.is_watertight and back.is_winding_consistent)
