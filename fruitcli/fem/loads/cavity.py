"""Cavity volume, its gradient and Hessian for walls made of 3- or 6-node triangles.

V = 1/3 int x . n dA over the closed wall (normals out of the cavity), integrated on
each triangle's reference element: with the tangents x_xi, x_eta,
V = 1/3 sum_q w_q x . (x_xi x x_eta), dV/dx_a = sum_q w_q N_a (x_xi x x_eta) (exact
for a closed wall), and d2V/dx_a dx_b = sum_q w_q N_a (dN_b/deta [x_xi]x -
dN_b/dxi [x_eta]x), symmetrized. The rules (`lagrange.tri_rule`) integrate each exactly.
Units: mm, mm^2, mm^3.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from fruitcli.fem.elements.lagrange import tri_rule, tri_shape, tri_shape_gradients


class Wall:
    """One cavity's wall: triangles (t, 3 or 6) of node indices."""

    def __init__(self, tris: np.ndarray):
        self.tris = np.asarray(tris, np.int64)
        order = 1 if self.tris.shape[1] == 3 else 2
        pts, w = tri_rule(2 if order == 1 else 4)
        self.w = w
        self.n = tri_shape(pts, order)  # (q, nn)
        self.dn = tri_shape_gradients(pts, order)  # (q, nn, 2)
        # the Hessian's quadrature weights w_q N_a dN_b/dxi_k as (q, nn nn) per k: its
        # blocks are then two matrix products (one einsum took 2.7 ms per wall here)
        self.w_n_dn = [
            np.einsum("q,qa,qb->qab", w, self.n, self.dn[:, :, k]).reshape(len(w), -1)
            for k in (0, 1)
        ]

    def _frames(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        p = x[self.tris]  # (t, nn, 3)
        xq = np.einsum("qa,tai->tqi", self.n, p)
        xi = np.einsum("qa,tai->tqi", self.dn[:, :, 0], p)
        eta = np.einsum("qa,tai->tqi", self.dn[:, :, 1], p)
        return xq, xi, eta, np.cross(xi, eta)

    def volume(self, x: np.ndarray) -> float:
        xq, _, _, cr = self._frames(x)
        return float(np.einsum("q,tqi,tqi->", self.w, xq, cr) / 3.0)

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """(n, 3) dV/dx (mm^2)."""
        _, _, _, cr = self._frames(x)
        per = np.einsum("q,qa,tqi->tai", self.w, self.n, cr)
        out = np.zeros((len(x), 3))
        np.add.at(out, self.tris.ravel(), per.reshape(-1, 3))
        return out

    def hessian(self, x: np.ndarray, n_nodes: int) -> sp.coo_matrix:
        """(3 n, 3 n) d2V/dx2 (mm), symmetric."""
        _, xi, eta, _ = self._frames(x)

        def skew(v: np.ndarray) -> np.ndarray:  # (t, q, 3) -> (t, q, 3, 3), [v]x
            z = np.zeros(v.shape[:-1])
            return np.stack(
                [
                    np.stack([z, -v[..., 2], v[..., 1]], -1),
                    np.stack([v[..., 2], z, -v[..., 0]], -1),
                    np.stack([-v[..., 1], v[..., 0], z], -1),
                ],
                -2,
            )

        t, nn = self.tris.shape
        q = len(self.w)
        sx = skew(xi).transpose(1, 0, 2, 3).reshape(q, -1)  # (q, t 9)
        se = skew(eta).transpose(1, 0, 2, 3).reshape(q, -1)
        h = self.w_n_dn[1].T @ sx - self.w_n_dn[0].T @ se  # (nn nn, t 9): a, b, tri, i, j
        h = h.reshape(nn, nn, t, 3, 3).transpose(2, 0, 3, 1, 4).reshape(t, 3 * nn, 3 * nn)
        h = 0.5 * (h + np.transpose(h, (0, 2, 1)))
        dofs = (3 * self.tris[:, :, None] + np.arange(3)).reshape(t, 3 * nn)
        rows = np.repeat(dofs, 3 * nn, axis=1).ravel()
        cols = np.tile(dofs, (1, 3 * nn)).ravel()
        return sp.coo_matrix((h.ravel(), (rows, cols)), shape=(3 * n_nodes, 3 * n_nodes))
