"""Where points meet the body's surface, at rest or carried by a FEM state (mm): heights
under vertical lines (the bench's contact points), surface vertices moved with the tets,
and touch points projected onto the surface facing their taxel.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np

from fruitcli.geometry.mesh.distance import SurfaceDistance, unit_face_normals
from fruitcli.geometry.mesh.load import load_mesh
from fruitcli.geometry.state_mesh import StateMesh

_INSIDE_EPS = 1e-9  # barycentric tolerance of the vertical ray test


def surface_heights(xy_mm: np.ndarray, nodes_mm: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Highest z where vertical lines at (x, y) (P, 2) meet triangles (F, 3); NaN: miss."""
    a, b, c = (nodes_mm[tris[:, k]] for k in range(3))
    e1, e2 = (b - a)[:, :2], (c - a)[:, :2]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    ok = np.abs(det) > _INSIDE_EPS
    a, b, c, e1, e2, det = a[ok], b[ok], c[ok], e1[ok], e2[ok], det[ok]
    r = xy_mm[:, None, :] - a[None, :, :2]  # (P, F, 2)
    u = (r[..., 0] * e2[:, 1] - r[..., 1] * e2[:, 0]) / det
    v = (e1[:, 0] * r[..., 1] - e1[:, 1] * r[..., 0]) / det
    inside = (u >= -_INSIDE_EPS) & (v >= -_INSIDE_EPS) & (u + v <= 1 + _INSIDE_EPS)
    z = a[:, 2] + u * (b[:, 2] - a[:, 2]) + v * (c[:, 2] - a[:, 2])
    z = np.where(inside, z, -np.inf).max(axis=1)
    return np.where(np.isfinite(z), z, np.nan)


def carried_vertices(
    rest_nodes: np.ndarray, tets: np.ndarray, nodes: np.ndarray, vertices: np.ndarray
) -> np.ndarray:
    """Surface vertices (V, 3) mm at rest, moved with a FEM state: each vertex mapped
    barycentrically into its rest tet (corner nodes of `tets`), placed by the same weights
    on the deformed `nodes` (N, 3). Vertices just outside the tet mesh (its surface is a
    remeshed copy of this one) are extrapolated from the nearest tet."""
    from fruitcli.fem.elements.barycentric import apply, locate

    corners = np.asarray(tets)[:, :4]
    tet, weights, _ = locate(rest_nodes, corners, vertices)
    return apply(nodes, corners, tet, weights)


def taxel_surface_heights(xy_mm: np.ndarray, taxels_mm: np.ndarray) -> np.ndarray:
    """z of the taxels' surface (linear over their xy Delaunay triangles) at (P, 2); NaN
    outside."""
    from scipy.interpolate import LinearNDInterpolator

    f = LinearNDInterpolator(taxels_mm[:, :2], taxels_mm[:, 2])
    return np.asarray(f(xy_mm), dtype=float)


def body_surface(path: str | Path, unit: str = "mm") -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) mm and triangles (F, 3) of the body's closed surface at rest."""
    surf = load_mesh(path, unit)
    return np.asarray(surf.vertices, float), np.asarray(surf.faces, np.int64)


def contact_heights(
    xy: np.ndarray,
    taxels_mm: np.ndarray,
    states: StateMesh | None,
    state: int,
    surface: tuple[np.ndarray, np.ndarray] | None,
) -> tuple[np.ndarray, str]:
    """z (P,) mm where vertical lines at `xy` (P, 2) meet the body from above (NaN: miss),
    and what the surface was. `surface`: (vertices, triangles) of the body at rest or None."""
    if surface is not None:
        verts, tris = surface
        if states is None:
            return surface_heights(xy, verts, tris), "the body's reduced surface at rest"
        moved = carried_vertices(states.rest_nodes, states.tets, states.nodes_mm(state), verts)
        return (
            surface_heights(xy, moved, tris),
            f"the body's reduced surface carried by FEM state {state}",
        )
    if states is not None:
        return (
            surface_heights(xy, states.nodes_mm(state), states.surface_tris),
            f"the FEM boundary of state {state} (no body surface given)",
        )
    return (
        taxel_surface_heights(xy, taxels_mm),
        "the taxels' interpolated surface (no body surface given)",
    )


FACING_COS = 0.5  # a face "faces the same way" as a taxel's surface within 60 degrees


class SurfaceProjector:
    """Touch points moved to the nearest point of the body's surface (vertices, triangles
    at rest, outward; carried by FEM state `state` when states are given) among the faces
    that face the same way as the surface at the nearest taxel (`taxels_mm` (T, 3), in
    that state), so a thin body is not crossed to its far side. The N9 average of 3D
    taxels lies on a chord, inside a curved body. `project` may run on several threads."""

    def __init__(
        self,
        surface: tuple[np.ndarray, np.ndarray],
        states: StateMesh | None,
        state: int | None,
        taxels_mm: np.ndarray,
    ):
        from scipy.spatial import cKDTree

        verts, tris = surface
        if states is not None:
            assert state is not None  # states come with the state to carry the surface by
            verts = carried_vertices(states.rest_nodes, states.tets, states.nodes_mm(state), verts)
        self.normal = unit_face_normals(verts, tris)
        self.verts, self.tris = verts, tris
        self.distance = SurfaceDistance(verts, tris)  # the whole surface (the model's chart)
        _, _, self.own = self.distance.closest(taxels_mm)
        self.taxel_tree = cKDTree(taxels_mm)
        self._facing: dict[int, SurfaceDistance] = {}  # per taxel, made when first needed
        self._lock = threading.Lock()

    def _faces_of(self, k: int):
        with self._lock:
            if k not in self._facing:
                facing = self.normal @ self.normal[self.own[k]] > FACING_COS
                self._facing[k] = SurfaceDistance(self.verts, self.tris[facing])
            return self._facing[k]

    def project(self, xyz_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points (n, 3) mm -> (points on the surface (n, 3) mm, distances moved (n,) mm)."""
        if len(xyz_mm) == 0:
            return xyz_mm, np.zeros(0)
        _, nearest = self.taxel_tree.query(xyz_mm)
        points, dist = np.empty_like(xyz_mm), np.empty(len(xyz_mm))
        for k in np.unique(nearest):
            rows = np.flatnonzero(nearest == k)
            q, d, _ = self._faces_of(int(k)).closest(xyz_mm[rows])
            points[rows], dist[rows] = q, d
        return points, dist


def project_to_surface(
    xyz_mm: np.ndarray,
    surface: tuple[np.ndarray, np.ndarray],
    states: StateMesh | None,
    state: int | None,
    taxels_mm: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Touch points (n, 3) mm moved onto the body's surface (`SurfaceProjector`).
    -> (points, distances (n,) mm)."""
    if len(xyz_mm) == 0:
        return xyz_mm, np.zeros(0)
    return SurfaceProjector(surface, states, state, taxels_mm).project(xyz_mm)
