"""How closely a tet mesh's boundary follows the surface it meshes, and which points lie
outside the mesh by more than that.

A mesh of straight-sided tets cuts across a curved surface: between its boundary nodes
(which lie on the surface) the boundary runs inside a convex surface by up to the chord's
sag, about h^2 / (8 R) for elements of size h on a radius R (the default Fruit's mesh at
5 mm lies within 1.16 mm of its reduced surface; its taxels lie up to 0.49 mm and its
track points up to 1.08 mm outside the mesh). A point on the surface follows the body
by extrapolation from its nearest element, as it should.
A point farther out than the mesh's own deviation is off the body: that is what is
warned about. Lengths in mm.
"""

from __future__ import annotations

import numpy as np

MARGIN = 0.1
"""Points count as on the surface up to (1 + MARGIN) times the mesh's deviation from it
(the deviation is measured at the surface's vertices and face centres, not everywhere)."""

FLOOR = 1e-3
"""...and up to FLOOR times the boundary's edge length: a planar face, meshed exactly,
still leaves points on it outside by rounding."""


def deviation_mm(
    surface_vertices: np.ndarray,
    surface_faces: np.ndarray,
    nodes: np.ndarray,
    boundary_tris: np.ndarray,
) -> float:
    """Largest distance (mm) from the meshed surface (its vertices and face centres) to
    the tet mesh's boundary triangles."""
    from fruitcli.geometry.mesh.distance import TreeDistance

    v = np.asarray(surface_vertices, float)
    f = np.asarray(surface_faces, np.int64)
    probes = np.concatenate([v, v[f].mean(axis=1)])
    _, d, _ = TreeDistance(nodes, boundary_tris).closest(probes)
    return float(d.max()) if len(d) else 0.0


def tolerance_mm(deviation: float, edge_mm: float) -> float:
    """How far outside the mesh a point on the meshed surface may lie (mm), for a mesh
    whose boundary lies within `deviation` of it and has edges of about `edge_mm`."""
    return (1.0 + MARGIN) * deviation + FLOOR * edge_mm


def outside_mm(
    nodes: np.ndarray, boundary_tris: np.ndarray, points: np.ndarray, outside: np.ndarray
) -> np.ndarray:
    """Distance (mm) of each point (t, 3) outside the mesh: its distance to the boundary
    triangles where `outside` (barycentric, `barycentric.locate`) is positive, else 0."""
    points = np.asarray(points, float).reshape(-1, 3)
    out = np.zeros(len(points))
    off = np.flatnonzero(np.asarray(outside) > 0)
    if len(off):
        from fruitcli.geometry.mesh.distance import TreeDistance

        _, d, _ = TreeDistance(nodes, boundary_tris).closest(points[off])
        out[off] = d
    return out
