"""Topology of tet meshes: boundary faces (outward) and their connected shells."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

# faces opposite node 3, 2, 1, 0 ordered so that the normal points away from that node
_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def boundary_faces(nodes: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(f, 3) faces that belong to one tet only, oriented outward of the solid.
    Assumes positively oriented tets (positive signed volume)."""
    faces = tets[:, _FACES].reshape(-1, 3)
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[counts[inverse.ravel()] == 1]


def shells(tris: np.ndarray) -> np.ndarray:
    """(f,) label of the edge-connected component of each triangle."""
    f = len(tris)
    edges = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    owner = np.tile(np.arange(f), 3)
    _, inv = np.unique(edges, axis=0, return_inverse=True)
    inv = inv.ravel()
    order = np.argsort(inv, kind="stable")
    a, b = owner[order][:-1], owner[order][1:]
    same = inv[order][:-1] == inv[order][1:]
    g = sp.coo_matrix((np.ones(same.sum()), (a[same], b[same])), shape=(f, f))
    return sp.csgraph.connected_components(g, directed=False)[1]
