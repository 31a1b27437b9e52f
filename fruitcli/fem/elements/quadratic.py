"""The quadratic (10-node) mesh of a linear tet mesh: one node at the middle of every
edge, moved onto the analytic surface where an edge lies on an ellipsoid chamber, so
the chamber walls are curved (second-order accurate) instead of faceted."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fruitcli.fem.elements.lagrange import TET10_EDGES, TRI6_EDGES


def _edge_key(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    return lo.astype(np.int64) * n + hi


def quadratic_mesh(
    nodes: np.ndarray, tets: np.ndarray, tris: list[np.ndarray]
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """(nodes2 (n + e, 3), tets10 (m, 10), tris6 list of (t, 6)) for corner nodes
    (n, 3) mm, tets (m, 4) and surface triangles (t, 3) each. Corner nodes keep their
    numbers; edge nodes follow, at the edge midpoints."""
    n = len(nodes)
    ta, tb = tets[:, TET10_EDGES[:, 0]], tets[:, TET10_EDGES[:, 1]]
    keys = _edge_key(ta, tb, n)
    uniq, inverse = np.unique(keys.ravel(), return_inverse=True)
    lo, hi = uniq // n, uniq % n
    mid = 0.5 * (nodes[lo] + nodes[hi])
    nodes2 = np.vstack([nodes, mid])
    tets10 = np.hstack([tets, n + inverse.reshape(-1, 6)])
    out = []
    for t in tris:
        t = np.asarray(t, np.int64)
        if len(t) == 0:
            out.append(np.zeros((0, 6), np.int64))
            continue
        k = _edge_key(t[:, TRI6_EDGES[:, 0]], t[:, TRI6_EDGES[:, 1]], n)
        pos = np.searchsorted(uniq, k.ravel())
        if np.any(pos >= len(uniq)) or np.any(uniq[np.minimum(pos, len(uniq) - 1)] != k.ravel()):
            raise ValueError("a surface triangle's edge is not an edge of any tet")
        out.append(np.hstack([t, n + pos.reshape(-1, 3)]))
    return nodes2, tets10, out


def project_onto_ellipsoid(
    nodes: np.ndarray, idx: np.ndarray, center: Sequence[float], radii: Sequence[float]
) -> None:
    """Move nodes[idx] radially (in the ellipsoid's scaled frame) onto the ellipsoid
    |(x - center) / radii| = 1, in place."""
    c, r = np.asarray(center, float), np.asarray(radii, float)
    s = (nodes[idx] - c) / r
    nodes[idx] = c + r * s / np.linalg.norm(s, axis=1, keepdims=True)


CURVED_MIN_JACOBIAN = 0.2
"""An element curved onto a chamber keeps its straight edges where that would leave its
Jacobian anywhere below this fraction of the straight element's (a coarse wall on a
flat ellipsoid would otherwise fold its elements)."""


def curve_onto_ellipsoid(
    nodes: np.ndarray,
    tets10: np.ndarray,
    idx: np.ndarray,
    center: Sequence[float],
    radii: Sequence[float],
) -> int:
    """Move the edge nodes idx onto the ellipsoid (in place), except those of elements
    the curving would distort past CURVED_MIN_JACOBIAN; returns how many stay straight."""
    from fruitcli.fem.elements.lagrange import tet_rule, tet_shape_gradients

    straight = nodes[idx].copy()
    project_onto_ellipsoid(nodes, idx, center, radii)
    corner_lam = np.eye(4)
    pts = np.vstack([corner_lam, tet_rule(2)[0]])
    dref = tet_shape_gradients(pts, 2)  # (p, 10, 3)
    moved = np.zeros(len(nodes), bool)
    moved[idx] = True
    cand = np.flatnonzero(moved[tets10].any(axis=1))
    kept = np.ones(len(idx), bool)
    where = np.full(len(nodes), -1)
    where[idx] = np.arange(len(idx))
    for _ in range(10):
        x = nodes[tets10[cand]]
        det = np.linalg.det(np.einsum("mai,paj->mpij", x, dref))
        c = x[:, :4]
        ref = np.linalg.det(
            np.stack([c[:, 1] - c[:, 0], c[:, 2] - c[:, 0], c[:, 3] - c[:, 0]], axis=-1)
        )
        bad = cand[(det.min(axis=1) < CURVED_MIN_JACOBIAN * np.abs(ref))]
        if not len(bad):
            break
        revert = np.unique(where[tets10[bad]][where[tets10[bad]] >= 0])
        revert = revert[kept[revert]]
        if not len(revert):
            break
        nodes[idx[revert]] = straight[revert]
        kept[revert] = False
    return int((~kept).sum())
