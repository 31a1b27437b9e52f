"""Structured tet meshes for the studies: boxes split into 6 tets per cube (Kuhn split,
conforming across cubes), optionally with a cubic cavity whose faces form a chamber."""

from __future__ import annotations

import numpy as np

# the 6 tets of the unit cube sharing the main diagonal 0-7 (corner k = x + 2y + 4z)
_KUHN = np.array([[0, 1, 3, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 6, 4, 7], [0, 4, 5, 7],
                  [0, 5, 1, 7]])


def box_tets(size_mm, cells, keep=None) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (n, 3) mm and tets (m, 4) of [0, sx] x [0, sy] x [0, sz] cut into
    `cells` = (nx, ny, nz) cubes; `keep(i, j, k) -> bool` may drop cubes."""
    nx, ny, nz = cells
    sx, sy, sz = size_mm
    gx, gy, gz = (np.linspace(0, s, n + 1) for s, n in zip(size_mm, cells, strict=True))
    X, Y, Z = np.meshgrid(gx, gy, gz, indexing="ij")
    nodes = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])

    def nid(i, j, k):
        return (i * (ny + 1) + j) * (nz + 1) + k

    tets = []
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if keep is not None and not keep(i, j, k):
                    continue
                corners = [nid(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1))
                           for c in range(8)]
                tets.extend([[corners[a] for a in t] for t in _KUHN])
    tets = np.array(tets, dtype=np.int64)
    used = np.unique(tets)
    remap = -np.ones(len(nodes), np.int64)
    remap[used] = np.arange(len(used))
    return nodes[used], remap[tets]


def boundary_faces(tets: np.ndarray) -> np.ndarray:
    """Triangles (f, 3) that belong to exactly one tet."""
    faces = np.concatenate([tets[:, [0, 1, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 3]],
                            tets[:, [1, 2, 3]]])
    key = np.sort(faces, axis=1)
    _, idx, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
    return faces[idx[counts == 1]]


def hollow_box(outer_mm: float, cells: int, hole_cells: int):
    """A cube of side `outer_mm` with a centred cubic cavity of `hole_cells` cells.
    Returns nodes, tets and the cavity's triangles."""
    lo = (cells - hole_cells) // 2
    hi = lo + hole_cells

    def keep(i, j, k):
        return not (lo <= i < hi and lo <= j < hi and lo <= k < hi)

    nodes, tets = box_tets((outer_mm,) * 3, (cells,) * 3, keep)
    faces = boundary_faces(tets)
    c = nodes[faces].mean(axis=1)
    inner = np.all(np.abs(c - outer_mm / 2) < outer_mm / 2 - 1e-9, axis=1)
    return nodes, tets, faces[inner]
