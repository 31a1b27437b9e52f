"""Potentials with Dirichlet conductors, and capacitances from charge or field energy.

Units: mm, V, fF, fC. Conductors are sets of nodes held at one potential each; every
other boundary is insulating (zero normal field: a symmetry plane or the far boundary).
The charge on a conductor is the sum of K u over its nodes (the discrete Gauss law,
exact for the discrete field), its field energy u^T K u / 2.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from fruitcli.errors import SolverError

if TYPE_CHECKING:
    from collections.abc import Callable


def factorized(k_free: sp.csr_matrix) -> Callable[[np.ndarray], np.ndarray]:
    """A solver for the symmetric positive definite `k_free`: cholespy's Cholesky, or
    SuperLU when cholespy is missing. Returns f(b) -> x."""
    try:
        import cholespy
    except ImportError:  # pragma: no cover - cholespy is a dependency
        import scipy.sparse.linalg as spla

        lu = spla.splu(k_free.tocsc(), permc_spec="MMD_AT_PLUS_A")
        return lu.solve
    k = sp.csr_matrix(k_free)
    k.sort_indices()
    chol = cholespy.CholeskySolverD(
        k.shape[0],
        k.indptr.astype(np.int32),
        k.indices.astype(np.int32),
        k.data.astype(np.float64),
        cholespy.MatrixType.CSR,
    )

    def solve(b: np.ndarray) -> np.ndarray:
        b = np.ascontiguousarray(b, dtype=np.float64)
        x = np.empty_like(b)
        chol.solve(b, x)
        return x

    return solve


def solve_potential(k: sp.csr_matrix, fixed: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Potentials (N,) V with nodes `fixed` (f,) held at `values` (f,) V and no free
    charge elsewhere; K (N, N) from `assemble.stiffness`."""
    n = k.shape[0]
    fixed = np.asarray(fixed, np.int64)
    is_free = np.ones(n, bool)
    is_free[fixed] = False
    free = np.flatnonzero(is_free)
    u = np.zeros(n)
    u[fixed] = values
    if free.size == 0:
        return u
    k_ff = k[free][:, free]
    rhs = -(k[free][:, fixed] @ u[fixed])
    x = factorized(k_ff)(rhs)
    if not np.all(np.isfinite(x)):
        raise SolverError(
            "electrostatics: the potential is not finite (a region without any conductor?)"
        )
    u[free] = x
    return u


def conductor_charge(k: sp.csr_matrix, u: np.ndarray, nodes: np.ndarray) -> float:
    """Charge (fC) on the conductor made of `nodes`, for potentials `u` (V)."""
    return float((k[np.asarray(nodes, np.int64)] @ u).sum())


def field_energy(k: sp.csr_matrix, u: np.ndarray) -> float:
    """Field energy (fJ) u^T K u / 2."""
    return 0.5 * float(u @ (k @ u))


def two_conductor_capacitance(
    k: sp.csr_matrix, high: np.ndarray, low: np.ndarray, method: str = "charge"
) -> float:
    """Capacitance (fF) between conductors `high` (at 1 V) and `low` (at 0 V), nodes
    given by index; method "charge" (the charge on `high`) or "energy" (2 W / V^2)."""
    fixed = np.concatenate([high, low])
    values = np.concatenate([np.ones(len(high)), np.zeros(len(low))])
    u = solve_potential(k, fixed, values)
    if method == "energy":
        return 2.0 * field_energy(k, u)
    if method == "charge":
        return conductor_charge(k, u, high)
    raise ValueError(f"method: expected charge or energy, got {method!r}")


def mutual_capacitance(
    k: sp.csr_matrix, drive: np.ndarray, sense: np.ndarray, grounded: np.ndarray | None = None
) -> float:
    """Mutual capacitance (fF) from `drive` to `sense`: the charge drawn onto `sense`
    (held at 0 V with every `grounded` node) when `drive` is at 1 V, sign turned so that
    it is positive; what a CDC measures on a Tx-Rx crossing."""
    grounded = np.zeros(0, np.int64) if grounded is None else np.asarray(grounded, np.int64)
    low = np.unique(np.concatenate([sense, grounded]))
    fixed = np.concatenate([drive, low])
    values = np.concatenate([np.ones(len(drive)), np.zeros(len(low))])
    u = solve_potential(k, fixed, values)
    return -conductor_charge(k, u, sense)
