"""Linear solvers for the tangent system K_t dx = b over the free dofs.

K_t = consistent corotational tangent (R K0 R^T plus the rotation-derivative term,
projected to positive semi-definite per element; `corotation.exact_stiffness`) + spring
diagonal; with no deformation gradient given it is SOFA's warped R K0 R^T. Strategies, chosen
by name (`[solver] linear_solver`):

- ``splu``: modified Newton: a SuperLU factorization of K_t kept across Newton
  iterations and states and solved with directly; refreshed at the current
  configuration when the residual contracts by less than REFRESH_RATIO (default,
  fastest: one triangular solve per iteration);
- ``splu-pcg``: the kept factorization preconditions CG on the current matrix-free
  K_t (fewer Newton iterations, more work per iteration); refreshed when CG needs
  more than PCG_MAX_ITERATIONS;
- ``splu-fresh``: K_t assembled and factorized at every Newton iteration (reference);
- ``cg``: CG with a Jacobi preconditioner, no factorization (low memory).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse.linalg as spla

from fruitcli.errors import SolverError
from fruitcli.fem import corotation
from fruitcli.fem.tolerances import (
    PCG_MAX_ITERATIONS,
    PCG_RELATIVE_TOLERANCE,
    REFRESH_RATIO,
)

LINEAR_SOLVERS = ("splu", "splu-pcg", "splu-fresh", "cg")


class TangentSolver:
    """Solves with the tangent at the rotations given to `update`. Counts its work in
    `stats` (factorizations, cg_iterations, assembly_s, factor_s)."""

    def __init__(self, model, method: str = "splu"):
        if method not in LINEAR_SOLVERS:
            raise SolverError(f"[solver].linear_solver: expected one of "
                              f"{', '.join(LINEAR_SOLVERS)}, got {method!r}")
        self.model = model
        self.method = method
        self.rot = None
        self.f = None
        self.load_k = None
        self.matrix = None
        self.factor = None
        self.factor_kind = None
        self.kind = "warped"
        self.project = False
        self.diag = None
        self.refresh = False
        self.stats = {"factorizations": 0, "cg_iterations": 0, "assembly_s": 0.0,
                      "factor_s": 0.0}

    def update(self, rot: np.ndarray, f: np.ndarray | None = None, load_stiffness=None,
               project: bool = False) -> None:
        """Set the current element rotations (m, 3, 3) and deformation gradients (m, 3, 3)
        (without f, the tangent is the warped R K0 R^T), the sparse follower-pressure
        stiffness over the free dofs (or None) and whether the rotation term is projected
        to positive semi-definite per element."""
        self.rot, self.f, self.load_k, self.matrix = rot, f, load_stiffness, None
        self.project = project
        self.kind = "warped" if f is None else ("projected" if project else "exact")
        if self.method == "splu" and self.factor is not None and self.kind != self.factor_kind:
            self.refresh = True
        if self.method == "splu-fresh" or (self.method in ("splu", "splu-pcg")
                                           and (self.factor is None or self.refresh)):
            self._factorize()
            self.refresh = False
        elif self.method == "cg":
            self.diag = self._assemble().diagonal()

    def progress(self, ratio: float) -> None:
        """Told the residual ratio of the last Newton step; a slow contraction asks the
        reused factorization to be rebuilt at the next `update`."""
        if self.method in ("splu", "splu-pcg") and ratio > REFRESH_RATIO:
            self.refresh = True

    def _assemble(self):
        t0 = time.perf_counter()
        m = self.model
        k = m.pattern.assemble(m.tangent_blocks(self.rot, self.f, self.project),
                               m.spring_diag)
        if self.f is not None and self.load_k is not None:
            k = k + self.load_k
        self.stats["assembly_s"] += time.perf_counter() - t0
        self.matrix = k
        return k

    def _factorize(self) -> None:
        k = self._assemble().tocsc()
        t0 = time.perf_counter()
        try:
            self.factor = spla.splu(k, permc_spec="MMD_AT_PLUS_A")
        except RuntimeError as exc:
            raise SolverError(f"tangent stiffness is singular ({exc}); is the body held by "
                              "[[fixed]], [[jig]] or its rigid modes pinned?") from None
        self.factor_kind = self.kind
        self.stats["factor_s"] += time.perf_counter() - t0
        self.stats["factorizations"] += 1

    def matvec(self, v_free: np.ndarray) -> np.ndarray:
        if self.f is not None:
            if self.matrix is None:
                self._assemble()
            return self.matrix @ v_free
        m = self.model
        full = np.zeros(3 * m.n_nodes)
        full[m.pattern.free] = v_free
        out = corotation.apply_warped(m.k0, self.rot, m.tets, full.reshape(-1, 3)).reshape(-1)
        return out[m.pattern.free] + m.spring_diag * v_free

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve K_t X = rhs for rhs (n_free,) or (n_free, k)."""
        if self.method in ("splu", "splu-fresh"):
            return self.factor.solve(rhs)
        cols = rhs.reshape(len(rhs), -1)
        out = np.column_stack([self._pcg(c) for c in cols.T])
        return out.reshape(rhs.shape)

    def _pcg(self, b: np.ndarray) -> np.ndarray:
        n = len(b)
        a = spla.LinearOperator((n, n), matvec=self.matvec, dtype=float)
        if self.method == "cg":
            inv_d = 1.0 / self.diag
            prec = spla.LinearOperator((n, n), matvec=lambda v: inv_d * v, dtype=float)
            maxiter = 20 * PCG_MAX_ITERATIONS * 50
        else:
            prec = spla.LinearOperator((n, n), matvec=self.factor.solve, dtype=float)
            maxiter = PCG_MAX_ITERATIONS
        count = [0]

        def tick(_):
            count[0] += 1

        x, info = spla.cg(a, b, rtol=PCG_RELATIVE_TOLERANCE, maxiter=maxiter, M=prec,
                          callback=tick)
        self.stats["cg_iterations"] += count[0]
        if info == 0:
            return x
        if self.method == "cg":
            raise SolverError(f"CG did not converge in {maxiter} iterations "
                              "(try [solver].linear_solver = \"splu\")")
        self._factorize()  # stale preconditioner: refresh it and solve exactly
        return self.factor.solve(b)
