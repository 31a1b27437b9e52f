"""Chamber pressure: cavity volume and its gradient H (the constraint row of the paper's
eq. 3, SoftRobots' SurfacePressureConstraint).

A chamber is a closed triangle surface (t, 3) oriented with normals pointing out of
the cavity (into the silicone), so its enclosed volume is positive. Pressure p (kPa)
on it pushes the nodes with the force p * H (mN), H = dV/dx (mm^2).
"""

from __future__ import annotations

import numpy as np


def cavity_volume(x: np.ndarray, tris: np.ndarray) -> float:
    """Enclosed volume (mm^3) of a closed, outward oriented surface: sum x0.(x1 x x2)/6."""
    p = x[tris]
    return float(np.einsum("ti,ti->", p[:, 0], np.cross(p[:, 1], p[:, 2])) / 6.0)


def volume_gradient(x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """(n, 3) H = dV/dx: each triangle adds its area vector / 3 to its 3 vertices (mm^2)."""
    p = x[tris]
    area_vec = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]) / 6.0  # (area normal / 2) / 3
    out = np.zeros_like(x)
    for c in range(3):
        out[:, c] = np.bincount(tris.ravel(), np.repeat(area_vec[:, c], 3), minlength=len(x))
    return out


def orient_outward(x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """`tris` with a consistent winding (each edge traversed once each way, see
    `consistent_winding`), flipped if needed so that the enclosed volume is positive."""
    tris = consistent_winding(np.asarray(tris))
    return tris[:, [0, 2, 1]] if cavity_volume(x, tris) < 0.0 else tris


def consistent_winding(tris: np.ndarray) -> np.ndarray:
    """Flip triangles (t, 3) of a closed surface so that neighbours wind alike. Without
    it, V is not the enclosed volume and H not its gradient (pressure would then do work
    along closed paths). Raises ValueError when an edge does not have exactly two
    triangles (an open or non-manifold surface)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import breadth_first_order, connected_components

    t = len(tris)
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])  # (3t, 2)
    owner = np.tile(np.arange(t), 3)
    key = np.sort(e, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    if np.any(counts != 2):
        raise ValueError(f"{int(np.sum(counts != 2))} edge(s) not shared by exactly two "
                         "triangles (open or non-manifold surface)")
    order = np.argsort(inv, kind="stable")
    a, b = owner[order[0::2]], owner[order[1::2]]  # the two triangles of each edge
    same = e[order[0::2], 0] == e[order[1::2], 0]  # same direction: one must flip
    adj = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(t, t)).tocsr()
    flip = np.zeros(t, bool)
    rel = dict(zip(zip(a.tolist(), b.tolist(), strict=True), same.tolist(), strict=True))
    rel.update({(j, i): s for (i, j), s in rel.items()})
    _, labels = connected_components(adj, directed=False)
    for comp in np.unique(labels):
        start = int(np.flatnonzero(labels == comp)[0])
        nodes, pred = breadth_first_order(adj, start, directed=False)
        for v in nodes[1:]:  # build time only: one pass over the chamber's triangles
            u = int(pred[v])
            flip[v] = flip[u] ^ rel[(u, int(v))]
    out = tris.copy()
    out[flip] = out[flip][:, [0, 2, 1]]
    return out


def volume_hessian_coo(x: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, ...]:
    """(rows, cols, values) of the volume Hessian d^2V/dx^2 (mm) in global dofs
    3 * node + component, duplicates to be summed. For V_t = x0.(x1 x x2)/6 the blocks
    are d^2V/dx_a dx_b = -[x_c]x / 6 for (a, b, c) cyclic, their transposes for (b, a),
    and zero on the diagonal; the pressure's load stiffness is -p times this."""
    p = x[tris]  # (t, 3, 3)
    t = len(tris)
    cross = np.zeros((t, 3, 3, 3))  # [x_c]x per vertex c
    cross[:, :, 0, 1], cross[:, :, 0, 2] = -p[:, :, 2], p[:, :, 1]
    cross[:, :, 1, 0], cross[:, :, 1, 2] = p[:, :, 2], -p[:, :, 0]
    cross[:, :, 2, 0], cross[:, :, 2, 1] = -p[:, :, 1], p[:, :, 0]
    rows, cols, vals = [], [], []
    for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        blk = -cross[:, c] / 6.0  # (t, 3, 3) d^2V / dx_a dx_b
        for (i, j, v) in ((a, b, blk), (b, a, np.transpose(blk, (0, 2, 1)))):
            r = 3 * tris[:, i, None, None] + np.arange(3)[None, :, None]
            cc = 3 * tris[:, j, None, None] + np.arange(3)[None, None, :]
            rows.append(np.broadcast_to(r, v.shape).ravel())
            cols.append(np.broadcast_to(cc, v.shape).ravel())
            vals.append(v.ravel())
    return np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
