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
        raise ValueError(
            f"{int(np.sum(counts != 2))} edge(s) not shared by exactly two "
            "triangles (open or non-manifold surface)"
        )
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


def volume_hessian_pattern(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) of the volume Hessian d^2V/dx^2 in global dofs 3 * node + component,
    duplicates to be summed (they depend on the triangles only). For V_t = x0.(x1 x x2)/6
    the blocks are d^2V/dx_a dx_b = -[x_c]x / 6 for (a, b, c) cyclic, their transposes for
    (b, a), and zero on the diagonal; the pressure's load stiffness is -p times this."""
    rows, cols = [], []
    shape = (len(tris), 3, 3)
    for a, b, _ in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        for i, j in ((a, b), (b, a)):
            r = 3 * tris[:, i, None, None] + np.arange(3)[None, :, None]
            cc = 3 * tris[:, j, None, None] + np.arange(3)[None, None, :]
            rows.append(np.broadcast_to(r, shape).ravel())
            cols.append(np.broadcast_to(cc, shape).ravel())
    return np.concatenate(rows), np.concatenate(cols)


def volume_hessian_values(x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """The Hessian's values (mm) at x, in the order of `volume_hessian_pattern`:
    per cyclic (a, b, c) the block -[x_c]x / 6 of (a, b), then its transpose [x_c]x / 6
    of (b, a)."""
    p = x[tris] / 6.0  # (t, 3, 3)
    t = len(tris)
    out = np.zeros((3, 2, t, 3, 3))
    for k, c in enumerate((2, 0, 1)):
        xc, yc, zc = p[:, c, 0], p[:, c, 1], p[:, c, 2]
        blk = out[k, 0]  # -[x_c]x / 6
        blk[:, 0, 1], blk[:, 0, 2] = zc, -yc
        blk[:, 1, 0], blk[:, 1, 2] = -zc, xc
        blk[:, 2, 0], blk[:, 2, 1] = yc, -xc
        out[k, 1] = -blk  # its transpose ([x]x is skew)
    return out.reshape(-1)
