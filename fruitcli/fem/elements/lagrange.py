"""Lagrange tetrahedra (4 and 10 nodes) and triangles (3 and 6 nodes): shape functions
of the barycentric coordinates, their gradients on the reference element and the
quadrature rules that integrate what the FEM needs exactly.

Node order (VTK's): corners 0-3, then the edges (0,1), (1,2), (0,2), (0,3), (1,3),
(2,3) for tet10; corners 0-2, then (0,1), (1,2), (2,0) for tri6.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from fruitcli.fem.elements.families import ELEMENT_FAMILIES, ElementFamily

TET10_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]])
TRI6_EDGES = np.array([[0, 1], [1, 2], [2, 0]])


def tet_shape(lam: np.ndarray, order: int) -> np.ndarray:
    """(..., 4 or 10) shape function values at barycentric coordinates lam (..., 4)."""
    lam = np.asarray(lam, float)
    if order == 1:
        return lam.copy()
    corner = lam * (2.0 * lam - 1.0)
    edge = 4.0 * lam[..., TET10_EDGES[:, 0]] * lam[..., TET10_EDGES[:, 1]]
    return np.concatenate([corner, edge], axis=-1)


def tet_shape_gradients(lam: np.ndarray, order: int) -> np.ndarray:
    """(..., 4 or 10, 3) gradients of the shape functions with respect to the reference
    coordinates (xi1, xi2, xi3), lam = (1 - xi1 - xi2 - xi3, xi1, xi2, xi3)."""
    lam = np.asarray(lam, float)
    dlam = np.array([[-1.0, -1.0, -1.0], [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    if order == 1:
        return np.broadcast_to(dlam, lam.shape[:-1] + (4, 3)).copy()
    corner = (4.0 * lam - 1.0)[..., :, None] * dlam
    a, b = TET10_EDGES[:, 0], TET10_EDGES[:, 1]
    edge = 4.0 * (lam[..., a, None] * dlam[b] + lam[..., b, None] * dlam[a])
    return np.concatenate([corner, edge], axis=-2)


def tri_shape(lam: np.ndarray, order: int) -> np.ndarray:
    """(..., 3 or 6) triangle shape functions at barycentric coordinates lam (..., 3)."""
    lam = np.asarray(lam, float)
    if order == 1:
        return lam.copy()
    corner = lam * (2.0 * lam - 1.0)
    edge = 4.0 * lam[..., TRI6_EDGES[:, 0]] * lam[..., TRI6_EDGES[:, 1]]
    return np.concatenate([corner, edge], axis=-1)


def tri_shape_gradients(lam: np.ndarray, order: int) -> np.ndarray:
    """(..., 3 or 6, 2) gradients with respect to (xi, eta), lam = (1 - xi - eta, xi, eta)."""
    lam = np.asarray(lam, float)
    dlam = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])
    if order == 1:
        return np.broadcast_to(dlam, lam.shape[:-1] + (3, 2)).copy()
    corner = (4.0 * lam - 1.0)[..., :, None] * dlam
    a, b = TRI6_EDGES[:, 0], TRI6_EDGES[:, 1]
    edge = 4.0 * (lam[..., a, None] * dlam[b] + lam[..., b, None] * dlam[a])
    return np.concatenate([corner, edge], axis=-2)


def tet_rule(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Points (q, 4) as barycentric coordinates and weights (q,) summing to 1/6 (the
    reference tet's volume), exact for polynomials of `degree` (1 or 2)."""
    if degree <= 1:
        return np.full((1, 4), 0.25), np.array([1.0 / 6.0])
    a, b = 0.5854101966249685, 0.1381966011250105
    pts = np.full((4, 4), b)
    np.fill_diagonal(pts, a)
    return pts, np.full(4, 1.0 / 24.0)


def tri_rule(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Points (q, 3) as barycentric coordinates and weights (q,) summing to 1/2, exact
    for polynomials of `degree`: 2 (3 points) or 4 (Dunavant's 6 points)."""
    if degree <= 2:
        pts = np.full((3, 3), 1.0 / 6.0)
        np.fill_diagonal(pts, 2.0 / 3.0)
        return pts, np.full(3, 1.0 / 6.0)
    a, wa = 0.445948490915965, 0.223381589678011
    b, wb = 0.091576213509771, 0.109951743655322
    rows = []
    for s, _ in ((a, wa), (b, wb)):
        for k in range(3):
            p = np.full(3, s)
            p[k] = 1.0 - 2.0 * s
            rows.append(p)
    return np.array(rows), 0.5 * np.repeat([wa, wb], 3)


@dataclass(frozen=True)
class Family(ElementFamily):
    """An element family (`families.ElementFamily`) with its quadrature rules: the volume
    rule for stiffness and the surface rule for cavity volumes."""

    def volume_rule(self) -> tuple[np.ndarray, np.ndarray]:
        return tet_rule(self.volume_degree)

    def surface_rule(self) -> tuple[np.ndarray, np.ndarray]:
        return tri_rule(self.surface_degree)


ELEMENTS = {name: Family(**asdict(f)) for name, f in ELEMENT_FAMILIES.items()}
"""[fem].element values (`families.ELEMENT_FAMILIES`), with their rules."""


def family(name: str) -> Family:
    return ELEMENTS[name]
