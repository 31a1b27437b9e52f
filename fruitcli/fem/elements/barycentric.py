"""Barycentric mapping of points (taxels) into a tet mesh (the paper's Sec. IV-A).

Each point is mapped once, at rest, into the tet that contains it, or, for a point
just outside the mesh, the candidate tet it is least outside of (weights then
extrapolate, as SOFA's BarycentricMapping does). Positions in mm.
"""

from __future__ import annotations

import numpy as np

CANDIDATES = 16
"""Tets (by nearest centroid) examined per point."""


def barycentric_coordinates(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(t, 4) weights of points (t, 3) in tets given by their corners (t, 4, 3)."""
    d = np.transpose(corners[:, 1:] - corners[:, :1], (0, 2, 1))
    v = np.linalg.solve(d, (points - corners[:, 0])[:, :, None])[:, :, 0]
    return np.column_stack([1.0 - v.sum(axis=1), v])


def locate(
    nodes: np.ndarray, tets: np.ndarray, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For points (t, 3): containing tet (t,), weights (t, 4), and how far outside
    (t,) as -min(weight) clipped at 0 (0 for points inside)."""
    from scipy.spatial import cKDTree

    points = np.asarray(points, float).reshape(-1, 3)
    if len(points) == 0:
        return np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros(0)
    centroids = nodes[tets].mean(axis=1)
    k = min(CANDIDATES, len(tets))
    _, cand = cKDTree(centroids).query(points, k=k)
    cand = np.asarray(cand).reshape(len(points), k)
    corners = nodes[tets[cand.ravel()]]
    w = barycentric_coordinates(np.repeat(points, k, axis=0), corners).reshape(len(points), k, 4)
    best = np.argmax(w.min(axis=2), axis=1)
    rows = np.arange(len(points))
    weights = w[rows, best]
    return cand[rows, best], weights, np.clip(-weights.min(axis=1), 0.0, None)


def apply(
    x: np.ndarray, tets: np.ndarray, tet_index: np.ndarray, weights: np.ndarray
) -> np.ndarray:
    """Mapped positions (t, 3) for node positions x (n, 3), or (s, n, 3) -> (s, t, 3)."""
    corners = x[..., tets[tet_index], :]  # (..., t, 4, 3)
    return np.einsum("...tai,ta->...ti", corners, weights)
