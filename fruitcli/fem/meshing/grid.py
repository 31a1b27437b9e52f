"""Structured tet meshes of a box, built in numpy (tests, sweeps, flat pads).

Each hexahedral cell is split into 6 tets around a main diagonal (Kuhn); cells are
mirrored by the parity of their index so that the mesh is conforming and has no
preferred diagonal direction (a uniform split biases bending, sofa #5751).
"""

from __future__ import annotations

import itertools

import numpy as np

# Kuhn split of the unit cube: each tet follows one path (0,0,0) -> (1,1,1) along axes.
_KUHN = []
for perm in itertools.permutations(range(3)):
    corner = [0, 0, 0]
    path = [tuple(corner)]
    for axis in perm:
        corner[axis] = 1
        path.append(tuple(corner))
    _KUHN.append(path)


def structured_box(lo_mm, hi_mm, cells) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (n, 3) mm and tets (m, 4) filling the box [lo, hi] with cells = (nx, ny, nz)."""
    lo, hi = np.asarray(lo_mm, float), np.asarray(hi_mm, float)
    nx, ny, nz = (int(c) for c in cells)
    axes = [np.linspace(lo[d], hi[d], n + 1) for d, n in enumerate((nx, ny, nz))]
    gx, gy, gz = np.meshgrid(*axes, indexing="ij")
    nodes = np.column_stack([gx.ravel(), gy.ravel(), gz.ravel()])

    def node_id(i, j, k):
        return (i * (ny + 1) + j) * (nz + 1) + k

    ci, cj, ck = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    ci, cj, ck = ci.ravel(), cj.ravel(), ck.ravel()
    pi, pj, pk = ci % 2, cj % 2, ck % 2
    tets = []
    for path in _KUHN:
        corners = [node_id(ci + (a ^ pi), cj + (b ^ pj), ck + (c ^ pk)) for a, b, c in path]
        tets.append(np.stack(corners, axis=1))
    tets = np.concatenate(tets)
    p = nodes[tets]
    vol = np.einsum("mi,mi->m", p[:, 1] - p[:, 0],
                    np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
    neg = vol < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return nodes, tets


def structured_box_with_cavity(lo_mm, hi_mm, cells, cavity_lo_mm, cavity_hi_mm):
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
