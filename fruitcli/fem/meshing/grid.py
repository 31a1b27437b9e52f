"""Structured tet meshes of a box, built in numpy (tests, sweeps, flat pads).

Each hexahedral cell is split into 6 tets around a main diagonal (Kuhn); cells are
mirrored by the parity of their index so that the mesh is conforming and has no
preferred diagonal direction (a uniform split biases bending, sofa #5751).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

# Kuhn split of the unit cube: each tet follows one path (0,0,0) -> (1,1,1) along axes.
_KUHN = []
for perm in itertools.permutations(range(3)):
    corner = [0, 0, 0]
    path = [tuple(corner)]
    for axis in perm:
        corner[axis] = 1
        path.append(tuple(corner))
    _KUHN.append(path)


def structured_box(
    lo_mm: ArrayLike, hi_mm: ArrayLike, cells: Sequence[int]
) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (n, 3) mm and tets (m, 4) filling the box [lo, hi] with cells = (nx, ny, nz)."""
    lo, hi = np.asarray(lo_mm, float), np.asarray(hi_mm, float)
    nx, ny, nz = (int(c) for c in cells)
    axes = [np.linspace(lo[d], hi[d], n + 1) for d, n in enumerate((nx, ny, nz))]
    gx, gy, gz = np.meshgrid(*axes, indexing="ij")
    nodes = np.column_stack([gx.ravel(), gy.ravel(), gz.ravel()])

    def node_id(i: np.ndarray, j: np.ndarray, k: np.ndarray) -> np.ndarray:
        return (i * (ny + 1) + j) * (nz + 1) + k

    gi, gj, gk = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    ci, cj, ck = gi.ravel(), gj.ravel(), gk.ravel()
    pi, pj, pk = ci % 2, cj % 2, ck % 2
    parts = []  # (cells, 4) per tet of the Kuhn split
    for path in _KUHN:
        corners = [node_id(ci + (a ^ pi), cj + (b ^ pj), ck + (c ^ pk)) for a, b, c in path]
        parts.append(np.stack(corners, axis=1))
    tets = np.concatenate(parts)
    p = nodes[tets]
    vol = np.einsum("mi,mi->m", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
    neg = vol < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return nodes, tets


def structured_box_with_cavity(
    lo_mm: ArrayLike,
    hi_mm: ArrayLike,
    cells: Sequence[int],
    cavity_lo_mm: ArrayLike,
    cavity_hi_mm: ArrayLike,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Structured box minus the cells whose centre lies in the cavity box. Returns nodes
    (n, 3), tets (m, 4) and the cavity wall triangles (t, 3), normals out of the cavity."""
    from fruitcli.fem.meshing.topology import boundary_faces

    nodes, tets = structured_box(lo_mm, hi_mm, cells)
    c = nodes[tets].mean(axis=1)
    inside = np.all((c > np.asarray(cavity_lo_mm)) & (c < np.asarray(cavity_hi_mm)), axis=1)
    tets = tets[~inside]
    used = np.unique(tets)
    remap = np.full(len(nodes), -1)
    remap[used] = np.arange(len(used))
    nodes, tets = nodes[used], remap[tets]
    faces = boundary_faces(nodes, tets)
    lo, hi = nodes.min(axis=0), nodes.max(axis=0)
    on_outer = np.any(np.isclose(nodes[faces], lo) | np.isclose(nodes[faces], hi), axis=2)
    cavity = faces[~np.all(on_outer, axis=1)]
    return nodes, tets, cavity[:, [0, 2, 1]]


def shell_octant(
    inner_mm: float, outer_mm: float, cells: int, layers: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The octant x, y, z >= 0 of a spherical shell inner_mm <= r <= outer_mm as tets:
    three cubed-sphere patches (the cube faces x = 1, y = 1, z = 1 seen from the centre,
    equiangular), `cells` cells along each patch edge and `layers` radially, each cell
    split like `structured_box` (mirrored Kuhn). Every corner node lies on its sphere
    and the symmetry planes. Returns nodes (n, 3) mm, tets (m, 4) positive, and the
    inner wall's triangles (t, 3), normals out of the cavity (toward +r)."""
    from fruitcli.fem.meshing.topology import boundary_faces

    n, nl = int(cells), int(layers)
    if n < 1 or nl < 1 or not 0 < inner_mm < outer_mm:
        raise ValueError("shell_octant: expected 0 < inner_mm < outer_mm, cells, layers >= 1")
    t = np.tan(np.pi / 4 * np.arange(n + 1) / n)  # cube coordinate per index
    t[-1] = 1.0
    keys: dict[tuple[int, ...], int] = {}
    rows: list[list[int]] = []  # each tet's nodes
    points: list[np.ndarray] = []

    def node(cube: tuple[int, ...], k: int) -> int:  # cube: integer cube coordinates
        key = (*cube, k)
        if key not in keys:
            c = t[list(cube)]
            r = inner_mm + (outer_mm - inner_mm) * k / nl
            keys[key] = len(points)
            points.append(r * c / np.linalg.norm(c))
        return keys[key]

    for face in range(3):
        a, b = [d for d in range(3) if d != face]
        for i, j, k in itertools.product(range(n), range(n), range(nl)):
            p = (i % 2, j % 2, k % 2)
            for path in _KUHN:
                ids = []
                for c in path:
                    cube = [0, 0, 0]
                    cube[face], cube[a], cube[b] = n, i + (c[0] ^ p[0]), j + (c[1] ^ p[1])
                    ids.append(node(tuple(cube), k + (c[2] ^ p[2])))
                rows.append(ids)
    nodes, tets = np.array(points), np.array(rows, np.int64)
    q = nodes[tets]
    vol = np.einsum("mi,mi->m", q[:, 1] - q[:, 0], np.cross(q[:, 2] - q[:, 0], q[:, 3] - q[:, 0]))
    tets[vol < 0] = tets[vol < 0][:, [0, 2, 1, 3]]
    faces = boundary_faces(nodes, tets)
    r = np.linalg.norm(nodes, axis=1)
    inner = np.all(np.isclose(r[faces], inner_mm), axis=1)
    return nodes, tets, faces[inner][:, [0, 2, 1]]
