"""Tet quality measures in numpy (angles in degrees)."""

from __future__ import annotations

import numpy as np

_EDGES = [(0, 1, 2, 3), (0, 2, 1, 3), (0, 3, 1, 2), (1, 2, 0, 3), (1, 3, 0, 2), (2, 3, 0, 1)]


def dihedral_angles_deg(nodes: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(m, 6) interior dihedral angles (degrees) at the six edges of each tet."""
    p = nodes[tets]
    out = np.empty((len(tets), 6))
    for k, (a, b, c, d) in enumerate(_EDGES):
        e = p[:, b] - p[:, a]
        e /= np.linalg.norm(e, axis=1, keepdims=True)
        u = p[:, c] - p[:, a]
        v = p[:, d] - p[:, a]
        u -= np.einsum("mi,mi->m", u, e)[:, None] * e
        v -= np.einsum("mi,mi->m", v, e)[:, None] * e
        cos = np.einsum("mi,mi->m", u, v) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
        out[:, k] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return out


def min_dihedral_deg(nodes: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(m,) smallest dihedral angle of each tet (degrees)."""
    return dihedral_angles_deg(nodes, tets).min(axis=1)
