"""Linear solves with the hyperelastic model's tangent (`ContinuumModel.tangent`): the
tangent is assembled at every Newton step (its element blocks come from the compiled
element loop); `pcg` (default) solves it by CG preconditioned with a sparse factor
(MKL PARDISO in single precision, `pardiso.py`, refactorized numerically on its kept
analysis; SuperLU in symmetric mode without it) kept across Newton steps and states and
refreshed when CG slows down, `direct` factorizes it (double precision) at every step.
With PARDISO there is no other factorization: a tangent it cannot factor (singular)
fails the Newton step, which then takes the next tangent (`newton.TANGENTS`). Several
right-hand sides (a volume-controlled chamber's Newton step solves for the residual and
the chamber's volume gradient) run their CG in lockstep (`pcg_columns`): PARDISO's
solve with two right-hand sides took 60 % of two solves on the quadratic default Fruit.
Once the kept factor is symmetric indefinite (a tangent past a limit point), the Krylov
method is GMRES (`gmres_right`) instead of CG; `stats["cg_iterations"]` counts both.
Same interface as `fruitcli.fem.solver.linsolve.TangentSolver`."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np
import scipy.sparse.linalg as spla

from fruitcli.errors import SolverError
from fruitcli.fem import threads
from fruitcli.fem.solver import linsolve, pardiso
from fruitcli.fem.solver.linsolve import Factor, kept_estimate, pcg, upper_triangle
from fruitcli.fem.solver.solvers import LINEAR_SOLVERS
from fruitcli.fem.tolerances import (
    PCG_MAX_ITERATIONS,
    PCG_REFRESH_ITERATIONS,
    PCG_RELATIVE_TOLERANCE,
)

if TYPE_CHECKING:
    import scipy.sparse as sp

    from fruitcli.fem.solver.assemble import CsrPattern


SYMMETRIC_PIVOT_THRESHOLD = 0.01
"""Without PARDISO the tangent is factorized by SuperLU in symmetric mode: a diagonal
pivot is kept unless it is smaller than this fraction of its column's largest entry, so
the symmetric fill-reducing ordering mostly holds, whether or not the tangent is
positive definite (a partial-pivoting LU fills far more). On the default Fruit's
breathing (quadratic elements, 44,403 dofs; `tests/performance/bench_linear_solver.py`)
the 13 states took 113-154 s of solves this way against 33-45 s with PARDISO (three
runs on a shared 2-core machine), while cholespy's Cholesky (BLAS-free: 28-54 s per
factorization) did not finish the first state within its 300 s budget."""


def factorize(
    k: sp.csr_matrix,
    previous: Factor | None = None,
    single: bool = False,
    indefinite: bool = False,
) -> Factor:
    """A factor of the sparse symmetric k with `.solve` and `.single` (whether its
    solves are only approximate): MKL PARDISO when installed (`pardiso.py`; in single
    precision with `single` when it passes its probe, else double; the numerical
    refactorization of `previous`, a factor this returned before, when the pattern and
    precision are the same; straight to the indefinite type with `indefinite`;
    SolverError when it fails), otherwise SuperLU in symmetric mode (checked on a solve),
    otherwise SuperLU's general LU."""
    if linsolve.USE_PARDISO and pardiso.available():
        k = k.tocsr()  # as assembled: no conversion (40 ms each way on the quadratic Fruit)
        previous = previous if isinstance(previous, pardiso.Pardiso) else None
        try:
            fac = pardiso.factorize_probed(k, upper_triangle(k), previous, single, indefinite)
        except pardiso.PardisoError as exc:
            fac, why = None, str(exc)
        else:
            why = "its solve misses the probe"
        if fac is not None:
            return fac
        # PARDISO tried positive definite and symmetric indefinite: a general LU would
        # cost minutes and gigabytes here (SuperLU on the quadratic system) for a
        # tangent that is singular anyway; Newton takes its next, safer tangent
        raise SolverError(
            f"tangent stiffness has no factor ({why}); is the body held by "
            "[[fixed]], [[jig]] or its rigid modes pinned?"
        )
    k = k.tocsc()
    try:  # SuperLU keeping the symmetric ordering where it can
        exact = _Exact(
            spla.splu(
                k,
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=SYMMETRIC_PIVOT_THRESHOLD,
                options={"SymmetricMode": True},
            )
        )
        if pardiso.passes_probe(k, exact, pardiso.DOUBLE_PROBE):
            return exact
    except RuntimeError:
        pass
    try:
        lu = spla.splu(k, permc_spec="MMD_AT_PLUS_A")
    except RuntimeError as exc:
        raise SolverError(
            f"tangent stiffness is singular ({exc}); is the body held by "
            "[[fixed]], [[jig]] or its rigid modes pinned?"
        ) from None
    return _Exact(lu)


class _Exact:
    """SuperLU's factor with the `single` flag of the others (False: an exact solve)."""

    single = False

    def __init__(self, lu: spla.SuperLU) -> None:
        self.lu = lu

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self.lu.solve(b)


def add_in_pattern(
    k: sp.csr_matrix, other: sp.spmatrix | sp.sparray, indices: np.ndarray
) -> sp.csr_matrix:
    """k + other for sparse k and other; when both are CSR matrices on the same sparsity
    pattern (their column indices those of `indices`, the model's pattern), by adding
    other's data into k's (about 2 ms instead of SciPy's 4.4-9.6 ms sum on the quadratic
    default Fruit; k is changed)."""
    same = (
        getattr(k, "format", "") == "csr"
        and getattr(other, "format", "") == "csr"
        and k.shape == other.shape
        and k.nnz == other.nnz == len(indices)
        and np.shares_memory(k.indices, indices)
        and np.shares_memory(other.indices, indices)
    )
    if not same:
        return k + other
    k.data += other.data
    return k


class ContinuumBody(Protocol):
    """What `ContinuumSolver` reads of the hyperelastic model (`continuum.ContinuumModel`):
    its free-dof pattern and its tangent over the free dofs at x (mN/mm)."""

    @property
    def pattern(self) -> CsrPattern: ...

    def tangent(self, x: np.ndarray, project: bool = False) -> sp.csr_matrix: ...


class ContinuumSolver:
    """Solves K_t dx = b over the free dofs at the configuration given to `update`."""

    def __init__(self, model: ContinuumBody, method: str = "pcg"):
        if method not in LINEAR_SOLVERS:
            raise SolverError(
                f"[solver].linear_solver: expected one of "
                f"{', '.join(LINEAR_SOLVERS)}, got {method!r}"
            )
        self.model, self.method = model, method
        self.k: sp.csr_matrix | None = None  # the tangent of the last `update` (mN/mm)
        self.factor: Factor | None = None
        self.single = method == "pcg" and linsolve.SINGLE_PRECISION  # of the next factor
        # a tangent found indefinite (past a limit point, a wall buckling): the next
        # factors skip the positive definite attempt, a failed analysis each
        self.indefinite = False
        self.refresh = False
        self.fresh = False
        self.rtol = PCG_RELATIVE_TOLERANCE
        # CG's displacement goal (`linsolve.pcg`; set by Newton)
        self.displacement_goal = (0.0, 1.0)
        # Newton's chord steps near the tolerance (`linsolve.NEAR_TOLERANCE`): on the
        # default Fruit's breathing the 12 states took 4.6-5.4 s instead of 6.2-6.4 s
        self.near_tolerance = linsolve.NEAR_TOLERANCE
        self.newton_c = 0.0
        # converged (load vector, x, p) for the next state's predictor (`fem_model.Kept`)
        self.history: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        # (dx/dp (n, 3, K), volume compliance (K, K)) at the first state (`predictor`)
        self.sensitivity: tuple[np.ndarray, np.ndarray] | None = None
        # the last `estimate`: (r, factorizations then, its solve)
        self.estimated: tuple[np.ndarray, int, np.ndarray] | None = None
        self.factor_seconds = 0.0  # the last factorization's (Newton's deadline looks ahead)
        pardiso.available()  # MKL loaded here, not inside the first state's time
        threads.one_blas_thread()
        threads.choose_element_threads()
        self.stats: dict[str, float] = {
            "factorizations": 0,
            "cg_iterations": 0,
            "assembly_s": 0.0,
            "factor_s": 0.0,
        }

    def update(
        self,
        rot: np.ndarray,
        f: np.ndarray | None = None,
        load_stiffness: sp.csr_matrix | None = None,
        project: bool = False,
    ) -> None:
        """Tangent at the configuration `rot` (= the model's state x, n x 3): the full
        tangent with the follower-pressure stiffness, or (project, or no f) each
        element's block clamped to positive semi-definite and no pressure stiffness."""
        t0 = time.perf_counter()
        project = project or f is None
        k = self.model.tangent(rot, project=project)
        if not project and load_stiffness is not None:
            k = add_in_pattern(k, load_stiffness, self.model.pattern.indices)
        self.k = k.tocsr()
        self.stats["assembly_s"] += time.perf_counter() - t0
        self.fresh = False
        if self.method != "pcg" or self.factor is None or self.refresh:
            self._factorize()

    def _factorize(self) -> None:
        t0 = time.perf_counter()
        try:
            self.factor = factor = factorize(
                self._tangent, self.factor, self.single, self.indefinite
            )
            mtype = factor.mtype if isinstance(factor, pardiso.Pardiso) else pardiso.SPD
            self.indefinite = self.indefinite or mtype == pardiso.SYMMETRIC_INDEFINITE
            # a tangent too ill-conditioned for single precision stays so: later
            # refreshes go to double precision at once
            self.single = self.single and factor.single
        except SolverError:
            self.factor = None  # spent: the next update factorizes afresh
            raise
        self.factor_seconds = time.perf_counter() - t0
        self.stats["factor_s"] += self.factor_seconds
        self.stats["factorizations"] += 1
        self.refresh, self.fresh = False, True

    @property
    def _kept(self) -> Factor:
        """The kept factor (RuntimeError before the first `update` made one)."""
        if self.factor is None:
            raise RuntimeError("ContinuumSolver: no factor before the first update")
        return self.factor

    @property
    def _tangent(self) -> sp.csr_matrix:
        """The tangent of the last `update` (RuntimeError before it)."""
        if self.k is None:
            raise RuntimeError("ContinuumSolver: no tangent before the first update")
        return self.k

    def estimate(self, r: np.ndarray) -> np.ndarray | None:
        """The kept factor's solve of r (n_free,): an estimate of K_t^-1 r (mm for r in
        mN), or None before the first update."""
        if self.factor is None:
            return None
        z = self.factor.solve(r)
        self.estimated = (r, int(self.stats["factorizations"]), z)
        return z

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve K_t X = rhs for rhs (n_free,) or (n_free, k)."""
        z0 = kept_estimate(self.estimated, rhs, int(self.stats["factorizations"]))
        if self.method != "pcg":
            return self._kept.solve(rhs) if z0 is None else z0
        if z0 is not None or rhs.ndim == 1:
            return self._solve_one(rhs, z0)
        if rhs.shape[1] == 1:
            return self._solve_one(rhs[:, 0])[:, None]
        return self._solve_columns(rhs)

    def _solve_columns(self, b: np.ndarray) -> np.ndarray:
        """`_solve_one` of each column of b (n_free, k), the columns' CG run in lockstep
        (`pcg_columns`): one preconditioner solve with k right-hand sides and one sparse
        product per step instead of k of each."""
        if self.fresh and not self._kept.single:
            return self._kept.solve(b)
        x, its, ok = self._krylov(b, 2 * PCG_REFRESH_ITERATIONS, stale=True)
        self.stats["cg_iterations"] += int(its.sum())
        self.refresh = self.refresh or bool(np.any(its[ok] > PCG_REFRESH_ITERATIONS))
        if ok.all():
            return x
        if self.fresh:  # a fresh single-precision factor that failed: double from now on
            self.single = False
        self._factorize()
        bad = np.flatnonzero(~ok)
        xb, its, ok = self._krylov(b[:, bad], PCG_MAX_ITERATIONS)
        self.stats["cg_iterations"] += int(its.sum())
        if not ok.all():
            xb[:, ~ok] = self._kept.solve(np.ascontiguousarray(b[:, bad[~ok]]))
        x[:, bad] = xb
        return x

    def _krylov(
        self, b: np.ndarray, limit: int, stale: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, iterations, converged) of each column of b: CG in lockstep
        (`pcg_columns`) preconditioned by a positive definite factor; GMRES
        (`gmres_right`) by a symmetric indefinite one (past a limit point the tangent is
        indefinite: CG stopped at negative curvature and each Newton step then cost a
        refactorization), column after column. With a `stale` factor, the columns after
        the first that GMRES does not converge on are left (not converged) for the next
        factor: past the thick sphere's collapse the second column's GMRES failed as the
        first had, 0.55 s of 24 iterations before the refactorization."""
        if not self._indefinite_factor():
            return pcg_columns(self._products, self._kept.solve, b, self.rtol, limit)
        k, solve = self._tangent, self._kept.solve
        x, its, ok = np.zeros_like(b), np.zeros(b.shape[1], int), np.zeros(b.shape[1], bool)
        for j in range(b.shape[1]):
            x[:, j], its[j], ok[j] = gmres_right(k.__matmul__, solve, b[:, j], self.rtol, limit)
            if stale and not ok[j]:
                break
        return x, its, ok

    def _indefinite_factor(self) -> bool:
        """True when the kept factor is PARDISO's symmetric indefinite one with negative
        pivots (iparm[22]): a positive definite tangent factored as indefinite (the
        solver's `indefinite` flag, a 3-2-1 support) keeps CG."""
        f = self.factor
        return isinstance(f, pardiso.Pardiso) and (
            f.mtype == pardiso.SYMMETRIC_INDEFINITE and int(f.iparm[22]) > 0
        )

    def _products(self, p: np.ndarray) -> np.ndarray:
        """K p for p (n_free, k), column by column (SciPy's product with a block of
        columns took 1.7-2.5 times as long as the separate products on the quadratic
        default Fruit)."""
        k = self._tangent
        return np.column_stack([k @ p[:, j] for j in range(p.shape[1])])

    def _solve_one(self, b: np.ndarray, z0: np.ndarray | None = None) -> np.ndarray:
        if self.fresh and not self._kept.single:
            return self._kept.solve(b) if z0 is None else z0
        if self._indefinite_factor():
            return self._solve_columns(b[:, None])[:, 0]
        x, its, ok = pcg(
            self._tangent.__matmul__,
            self._kept.solve,
            b,
            self.rtol,
            2 * PCG_REFRESH_ITERATIONS,
            z0,
            self.displacement_goal,
        )
        self.stats["cg_iterations"] += its
        if ok:
            self.refresh = self.refresh or its > PCG_REFRESH_ITERATIONS
            return x
        if self.fresh:  # a fresh single-precision factor that failed: double from now on
            self.single = False
        self._factorize()
        x, its, ok = pcg(
            self._tangent.__matmul__,
            self._kept.solve,
            b,
            self.rtol,
            PCG_MAX_ITERATIONS,
            None,
            self.displacement_goal,
        )
        self.stats["cg_iterations"] += its
        return x if ok else self._kept.solve(b)


def pcg_columns(
    matvec: Callable[[np.ndarray], np.ndarray],
    precond: Callable[[np.ndarray], np.ndarray],
    b: np.ndarray,
    rtol: float,
    maxiter: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`linsolve.pcg` from zero on each column of b (n, k), the columns in lockstep: each
    step applies `matvec` and `precond` to the columns still running at once (a
    factor's solve with k right-hand sides reads the factor once). Each column's
    iterates are those of its own CG; it stops as `pcg` does (converged, maxiter, or
    negative curvature, then its last iterate or its preconditioned residual). Returns
    (x (n, k), iterations (k,), converged (k,))."""
    n, k = b.shape
    x = np.zeros_like(b)
    its = np.zeros(k, np.int64)
    ok = np.zeros(k, bool)
    nb = np.linalg.norm(b, axis=0)
    run = np.flatnonzero(nb > 0.0)
    ok[nb == 0.0] = True
    if not len(run):
        return x, its, ok
    r = b[:, run].copy()
    z = np.asarray(precond(r)).reshape(n, len(run))
    p = z.copy()
    rz = np.einsum("ij,ij->j", r, z)
    for it in range(1, maxiter + 1):
        q = np.asarray(matvec(p)).reshape(n, len(run))
        pq = np.einsum("ij,ij->j", p, q)
        bent = ~(pq > 0.0)
        for j in np.flatnonzero(bent):  # negative curvature: stop this column
            its[run[j]] = it
            if it == 1:  # no iterate yet: the preconditioned residual
                x[:, run[j]] = z[:, j]
        alpha = np.where(bent, 0.0, rz / np.where(bent, 1.0, pq))
        x[:, run] += alpha * p
        r -= alpha * q
        done = ~bent & (np.linalg.norm(r, axis=0) <= rtol * nb[run])
        its[run[done]] = it
        ok[run[done]] = True
        keep = ~(bent | done)
        if not keep.any():
            return x, its, ok
        run, r, p, rz = run[keep], r[:, keep], p[:, keep], rz[keep]
        z = np.asarray(precond(np.ascontiguousarray(r))).reshape(n, len(run))
        rz_new = np.einsum("ij,ij->j", r, z)
        p = z + (rz_new / rz) * p
        rz = rz_new
    its[run] = maxiter
    return x, its, ok


def gmres_right(
    matvec: Callable[[np.ndarray], np.ndarray],
    precond: Callable[[np.ndarray], np.ndarray],
    b: np.ndarray,
    rtol: float,
    maxiter: int,
) -> tuple[np.ndarray, int, bool]:
    """GMRES from zero (no restart) with right preconditioning, A M^-1 y = b, x = M^-1 y,
    for any nonsingular A and M (indefinite ones too): stops once |b - A x| <= rtol |b|
    (the least-squares residual, exact in exact arithmetic) or after `maxiter` steps.
    Returns (x, iterations, converged)."""
    nb = float(np.linalg.norm(b))
    if nb == 0.0:
        return np.zeros_like(b), 0, True
    v = [b / nb]
    z = []
    h = np.zeros((maxiter + 1, maxiter))
    g = np.zeros(maxiter + 1)
    g[0] = nb
    cs, sn = np.zeros(maxiter), np.zeros(maxiter)
    ok = False
    for j in range(maxiter):
        z.append(np.asarray(precond(v[j])).reshape(-1))
        w = np.asarray(matvec(z[j]), float).copy()
        for i in range(j + 1):  # modified Gram-Schmidt
            h[i, j] = float(w @ v[i])
            w -= h[i, j] * v[i]
        beta = float(np.linalg.norm(w))
        h[j + 1, j] = beta
        for i in range(j):  # the earlier Givens rotations on the new column
            h[i, j], h[i + 1, j] = (
                cs[i] * h[i, j] + sn[i] * h[i + 1, j],
                -sn[i] * h[i, j] + cs[i] * h[i + 1, j],
            )
        rho = float(np.hypot(h[j, j], beta))
        if rho == 0.0:  # A M^-1 singular on the Krylov space: keep the steps before
            z.pop()
            break
        cs[j], sn[j] = h[j, j] / rho, beta / rho
        h[j, j], h[j + 1, j] = rho, 0.0
        g[j], g[j + 1] = cs[j] * g[j], -sn[j] * g[j]
        ok = abs(g[j + 1]) <= rtol * nb
        if ok or beta == 0.0:  # converged, or the Krylov space is invariant (exact)
            ok = True
            break
        v.append(w / beta)
    n = len(z)
    y = np.linalg.solve(np.triu(h[:n, :n]), g[:n]) if n else np.zeros(0)
    x = np.column_stack(z) @ y if n else np.zeros_like(b)
    return x, n, bool(ok)
