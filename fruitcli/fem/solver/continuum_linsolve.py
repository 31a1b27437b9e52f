"""Linear solves with the hyperelastic model's tangent (`ContinuumModel.tangent`): the
tangent is assembled at every Newton step (its element blocks come from the compiled
element loop); `pcg` (default) solves it by CG preconditioned with a sparse Cholesky
factor kept across Newton steps and states and refreshed when CG slows down, `direct`
factorizes it at every step.
Same interface as `fruitcli.fem.solver.linsolve.TangentSolver`."""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse.linalg as spla

from fruitcli.errors import SolverError
from fruitcli.fem.solver.linsolve import _cholesky, pcg
from fruitcli.fem.tolerances import (
    PCG_MAX_ITERATIONS,
    PCG_REFRESH_ITERATIONS,
    PCG_RELATIVE_TOLERANCE,
)
from fruitcli.scene import LINEAR_SOLVERS


class _Pardiso:
    """MKL PARDISO (supernodal, multithreaded; through pypardiso) on the upper triangle
    of a symmetric k: positive definite first (mtype 2), indefinite otherwise (-2).
    On the quadratic default Fruit it factorizes about 8x faster than cholespy's
    simplicial Cholesky (`tests/bench/bench_fem.py --factor`)."""

    def __init__(self, k, previous=None):
        import pypardiso
        import scipy.sparse as sp

        self.a = sp.triu(k, format="csr")
        self.a.sort_indices()
        # the previous factor's PARDISO handle is taken over: a new PyPardisoSolver
        # searches the install for MKL's library (0.35 s of glob per factorization here)
        kept = {} if previous is None or previous.solver is None else \
            {previous.solver.mtype: previous.solver}
        if previous is not None:
            previous.solver = None
        for mtype in (2, -2):
            self.solver = kept.get(mtype) or pypardiso.PyPardisoSolver(mtype=mtype)
            self.solver.set_phase(12)
            try:
                self.solver.factorize(self.a)
                return
            except Exception:  # noqa: BLE001 - pypardiso raises its own error type
                continue
        raise RuntimeError("PARDISO could not factorize the tangent")

    def solve(self, b):
        b = np.asarray(b, float)
        x = self.solver.solve(self.a, b)
        return x.reshape(b.shape)

    def __del__(self):
        # MKL keeps the factor outside Python's heap until told (about 1 GB here)
        solver = getattr(self, "solver", None)
        if solver is not None:
            try:
                solver.free_memory(everything=True)
            except Exception:  # noqa: BLE001 - at interpreter exit MKL frees it anyway
                pass


try:
    import pypardiso  # noqa: F401
except ImportError:  # optional: cholespy or SuperLU instead (slower on quadratic tets)
    _Pardiso = None  # noqa: F811


def factorize(k, previous=None):
    """A factor of the sparse symmetric k with `.solve`: PARDISO when installed (reusing
    the handle of `previous`, a factor this returned before, which is then spent),
    otherwise Cholesky when k is positive definite (checked on a solve), otherwise LU."""
    k = k.tocsc()
    if _Pardiso is not None:
        try:
            fac = _Pardiso(k.tocsr(), previous if isinstance(previous, _Pardiso) else None)
            probe = np.ones(k.shape[0])
            sol = fac.solve(probe)
            if np.isfinite(sol).all() and np.linalg.norm(k @ sol - probe) \
                    <= 1e-6 * np.linalg.norm(probe):
                return fac
        except Exception:  # noqa: BLE001 - PARDISO's own errors: fall back to Cholesky/LU
            pass
    if _cholesky is not None:
        try:
            fac = _cholesky(k)
            probe = np.ones(k.shape[0])
            sol = fac.solve(probe)
            if np.isfinite(sol).all() and np.linalg.norm(k @ sol - probe) \
                    <= 1e-6 * np.linalg.norm(probe):
                return fac
        except (RuntimeError, ValueError):
            pass
    try:
        return spla.splu(k, permc_spec="MMD_AT_PLUS_A")
    except RuntimeError as exc:
        raise SolverError(f"tangent stiffness is singular ({exc}); is the body held by "
                          "[[fixed]], [[jig]] or its rigid modes pinned?") from None


class ContinuumSolver:
    """Solves K_t dx = b over the free dofs at the configuration given to `update`."""

    def __init__(self, model, method: str = "pcg"):
        if method not in LINEAR_SOLVERS:
            raise SolverError(f"[solver].linear_solver: expected one of "
                              f"{', '.join(LINEAR_SOLVERS)}, got {method!r}")
        self.model, self.method = model, method
        self.k = None
        self.factor = None
        self.refresh = False
        self.fresh = False
        self.rtol = PCG_RELATIVE_TOLERANCE
        self.newton_c = 0.0
        self.history = []
        self.sensitivity = None  # (n, 3, K) dx/dp at the first state (newton.py)
        self.stats = {"factorizations": 0, "cg_iterations": 0, "assembly_s": 0.0,
                      "factor_s": 0.0}

    def update(self, rot, f=None, load_stiffness=None, project: bool = False) -> None:
        """Tangent at the configuration `rot` (= the model's state x, n x 3): the full
        tangent with the follower-pressure stiffness, or (project, or no f) each
        element's block clamped to positive semi-definite and no pressure stiffness."""
        t0 = time.perf_counter()
        project = project or f is None
        k = self.model.tangent(rot, project=project)
        if not project and load_stiffness is not None:
            k = k + load_stiffness
        self.k = k.tocsr()
        self.stats["assembly_s"] += time.perf_counter() - t0
        self.fresh = False
        if self.method != "pcg" or self.factor is None or self.refresh:
            self._factorize()

    def _factorize(self) -> None:
        t0 = time.perf_counter()
        self.factor = factorize(self.k, self.factor)
        self.stats["factor_s"] += time.perf_counter() - t0
        self.stats["factorizations"] += 1
        self.refresh, self.fresh = False, True

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        if self.method != "pcg":
            return self.factor.solve(rhs)
        cols = rhs.reshape(len(rhs), -1)
        out = np.column_stack([self._solve_one(c) for c in cols.T])
        return out.reshape(rhs.shape)

    def _solve_one(self, b: np.ndarray) -> np.ndarray:
        if self.fresh:
            return self.factor.solve(b)
        x, its, ok = pcg(self.k.__matmul__, self.factor.solve, b, self.rtol,
                         2 * PCG_REFRESH_ITERATIONS)
        self.stats["cg_iterations"] += its
        if ok:
            self.refresh = self.refresh or its > PCG_REFRESH_ITERATIONS
            return x
        self._factorize()
        x, its, ok = pcg(self.k.__matmul__, self.factor.solve, b, self.rtol,
                         PCG_MAX_ITERATIONS)
        self.stats["cg_iterations"] += its
        return x if ok else self.factor.solve(b)
