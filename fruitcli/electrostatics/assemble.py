"""The stiffness matrix of electrostatics, div(eps grad phi) = 0, on Lagrange tetrahedra.

Units: mm, fF. K[a, b] = sum over elements of eps_e * integral grad N_a . grad N_b dV,
eps_e = eps0 * eps_r (fF/mm), so u^T K u / 2 is the field energy in fJ for potentials u
in V and K u is the charge (fC) on each node.

Elements: ``order`` 1 (4-node tets, one quadrature point) or 2 (10-node tets in VTK node
order, `fruitcli.fem.elements.lagrange`, isoparametric: the Jacobian is evaluated at
every quadrature point, so edge nodes moved onto a curved conductor curve the element).

Why fruit's own assembly and not a library's: scikit-fem 12.0.2 (BSD-3, numpy and
scipy only) was measured on the same gmsh meshes with its `BilinearForm` and a
per-element permittivity, giving the same matrices (to 6e-16 relative). Fruit's kernel
(batched matmuls over the reference gradients `fruitcli.fem.elements` already has)
assembled a linear 82,835-tet mesh (15,969 dofs) in 0.45 s against 0.71 s, and a
quadratic 18,164-tet mesh (28,001 dofs) in 0.56 s against 1.03 s (2 shared cores; a
run beside other jobs gave 1.33 s against 1.76 s and 0.52 s against 1.15 s;
`python tests/bench/bench_skin.py --assembly` prints both when scikit-fem is installed).
A library would add a dependency and a second node layout ((3, n) points) for a slower
result; nothing beyond the scalar Laplacian is needed.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from fruitcli.fem.elements.lagrange import tet_rule, tet_shape_gradients

EPS0_FF_PER_MM = 8.8541878128
"""Vacuum permittivity in fF/mm (8.854e-12 F/m)."""

NODES_PER_TET = {1: 4, 2: 10}


def element_stiffness(nodes: np.ndarray, tets: np.ndarray, order: int = 1) -> np.ndarray:
    """(m, n, n) integral of grad N_a . grad N_b over each element (mm), without eps;
    nodes (N, 3) mm, tets (m, 4) or (m, 10)."""
    if order not in NODES_PER_TET or tets.shape[1] != NODES_PER_TET[order]:
        raise ValueError(
            f"order {order} needs {NODES_PER_TET.get(order)} nodes per tet, got {tets.shape[1]}"
        )
    pts, weights = tet_rule(2 * (order - 1))
    dref = tet_shape_gradients(pts, order)  # (q, n, 3)
    x = nodes[tets]  # (m, n, 3)
    jac = x.transpose(0, 2, 1)[:, None] @ dref[None]  # (m, q, 3, 3): dx_i / dxi_j
    det = np.linalg.det(jac)
    if np.any(det <= 0):
        raise ValueError(f"{int((det <= 0).any(axis=1).sum())} inverted or flat elements")
    grads = dref[None] @ np.linalg.inv(jac)  # (m, q, n, 3)
    m, q, n, _ = grads.shape
    a = grads.transpose(0, 2, 1, 3).reshape(m, n, 3 * q)  # (m, n, q*3)
    w = np.repeat(det * weights[None, :], 3, axis=1)  # (m, q*3)
    return (a * w[:, None, :]) @ a.transpose(0, 2, 1)


def stiffness(
    nodes: np.ndarray, tets: np.ndarray, eps_r: np.ndarray | float = 1.0, order: int = 1
) -> sp.csr_matrix:
    """(N, N) CSR stiffness (fF) with relative permittivity `eps_r` per element (m,) or one
    value; nodes (N, 3) mm, tets (m, 4) for order 1 or (m, 10) for order 2."""
    tets = np.asarray(tets, np.int64)
    ke = element_stiffness(np.asarray(nodes, float), tets, order)
    eps = EPS0_FF_PER_MM * np.broadcast_to(np.asarray(eps_r, float), (len(tets),))
    n = tets.shape[1]
    rows = np.repeat(tets, n, axis=1).ravel()
    cols = np.tile(tets, (1, n)).ravel()
    data = (eps[:, None, None] * ke).ravel()
    size = len(nodes)
    return sp.coo_matrix((data, (rows, cols)), shape=(size, size)).tocsr()
