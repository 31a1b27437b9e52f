"""Linear solvers for the tangent system K_t dx = b over the free dofs.

K_t = consistent corotational tangent (R K0 R^T plus the rotation-derivative term;
`Model.apply_tangent`), optionally with the follower-pressure stiffness or with
the rotation term projected to positive semi-definite, + spring diagonal; with no
deformation gradient given it is SOFA's warped R K0 R^T. Strategies, chosen by name
(`[solver] linear_solver`):

- ``pcg`` (default): one sparse factorization (MKL PARDISO in single precision,
  `pardiso.py`; cholespy's Cholesky, then SuperLU in symmetric mode, when it is
  missing) of a positive definite
  tangent -- the projected one at the configuration where it was last refreshed -- is
  kept across Newton iterations and states and preconditions CG on the current tangent
  applied matrix-free (no assembly per iteration: assembling costs about 20 ms on the
  default Fruit, a product 0.2 ms over both cores). CG
  stops at the relative tolerance Newton asks for (`rtol`); the factorization is
  refreshed at the current configuration when CG needs more than
  PCG_REFRESH_ITERATIONS, or fails. Newton's last step of a state, once within
  NEAR_TOLERANCE of the tolerance, keeps the tangent (a chord step);
- ``direct``: K_t assembled and factorized at every Newton iteration (reference);
- ``jacobi``: CG with a Jacobi preconditioner, no factorization (low memory).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np
import scipy.sparse.linalg as spla

from fruitcli.errors import SolverError
from fruitcli.fem import threads
from fruitcli.fem.materials import corotation
from fruitcli.fem.materials import corotation_kernels as kernels
from fruitcli.fem.solver import pardiso
from fruitcli.fem.solver.solvers import LINEAR_SOLVERS
from fruitcli.fem.tolerances import (
    PCG_MAX_ITERATIONS,
    PCG_REFRESH_ITERATIONS,
    PCG_RELATIVE_TOLERANCE,
)

if TYPE_CHECKING:
    import scipy.sparse as sp

    from fruitcli.fem.solver.assemble import CsrPattern


class Factor(Protocol):
    """A sparse factor: `solve(b)` and `single` (whether its solves are only approximate:
    a single-precision one); SuperLU's factor, which lacks `single`, counts as exact."""

    single: bool

    def solve(self, b: np.ndarray) -> np.ndarray: ...


NEAR_TOLERANCE = 30.0
"""Newton's last step, once the residual is within this factor of the tolerance, keeps
the tangent (a chord step: no rotation term or pressure stiffness recomputed) and solves
only as far as crossing the tolerance needs (PCG_TARGET * tolerance / residual): the
tangent moved by about the previous step, 1e-2 relative or less, so the step still
leaves the residual well below the tolerance."""


USE_PARDISO = True
"""The kept factor is MKL PARDISO's when MKL's library loads (`pardiso.py`; pypardiso
brings it: a solve 0.44 ms against cholespy's 0.47 ms on the default Fruit, a numerical
refactorization 13 ms against cholespy's 74 ms factorization); False (the tests'
switch) takes cholespy, then SuperLU."""


SINGLE_PRECISION = True
"""Both solvers' kept PARDISO factor (`pcg`; this one and `continuum_linsolve`'s) is
single precision when it passes its probe (`pardiso.factorize_probed`). On the default
Fruit (`python tests/bench/bench_fem.py --factor`): with linear tets a solve takes
0.33 ms instead of 0.44 and a refactorization 8.7 ms instead of 13 (nodes within 1e-8
mm); with the quadratic element 13 ms instead of 20 and 0.32 s instead of 0.55 s (nodes
within 6e-7 mm); the same numbers of CG iterations. False (the tests' switch) keeps
double precision."""


def upper_triangle(k: sp.spmatrix | sp.sparray) -> sp.csr_matrix | sp.csr_array:
    """The upper triangle of the symmetric sparse k in CSR with sorted indices, of k's
    class. A CSR matrix in canonical form (sorted indices, no duplicates) takes its
    entries by the positions found for its pattern (`_UpperPick`, kept for the last
    pattern seen: every tangent of a body has the same): 5 ms instead of scipy's `triu`,
    37-56 ms on the quadratic default Fruit."""
    import scipy.sparse as sp

    if sp.issparse(k) and k.format == "csr" and k.has_canonical_format:
        pick = _UPPER_PICK[0]
        if pick is None or not pick.fits(k):
            pick = _UpperPick.of(k)
        if pick is not None:
            _UPPER_PICK[0] = pick
            nnz = int(k.indptr[-1])
            return type(k)((k.data[:nnz][pick.positions], pick.indices, pick.indptr), shape=k.shape)
    u = sp.triu(k, format="csr")
    u.sort_indices()
    return u


class _UpperPick:
    """Where the upper triangle's entries lie in the data of a CSR pattern (indptr,
    indices), and the triangle's own indptr and indices (read-only: every triangle of
    the pattern shares them)."""

    def __init__(self, indptr: np.ndarray, indices: np.ndarray) -> None:
        n = len(indptr) - 1
        rows = np.repeat(np.arange(n, dtype=indices.dtype), np.diff(indptr))
        kind = np.int32 if len(indices) < 2**31 else np.int64
        self.positions = np.flatnonzero(indices >= rows).astype(kind)
        self.indices = indices[self.positions]
        self.indptr = np.zeros(n + 1, np.int64)
        np.cumsum(np.bincount(rows[self.positions], minlength=n), out=self.indptr[1:])
        self.pattern = (indptr.copy(), indices.copy())
        for a in (self.positions, self.indices, self.indptr, *self.pattern):
            a.flags.writeable = False

    @classmethod
    def of(cls, k: sp.csr_matrix) -> _UpperPick | None:
        """The pick of k's pattern, or None when its indices are not strictly increasing
        along each row (a flag that says otherwise is not trusted)."""
        nnz = int(k.indptr[-1])
        indices = k.indices[:nnz]
        step = np.diff(indices)
        last_of_row = k.indptr[1:-1] - 1  # a row's last entry: the next row may restart
        inside = np.ones(len(step), bool)
        inside[last_of_row[(last_of_row >= 0) & (last_of_row < len(step))]] = False
        if np.any(step[inside] <= 0):
            return None
        return cls(k.indptr, indices)

    def fits(self, k: sp.csr_matrix) -> bool:
        """True when k has this pick's pattern."""
        indptr, indices = self.pattern
        return (
            int(k.indptr[-1]) == len(indices)
            and np.array_equal(k.indptr, indptr)
            and np.array_equal(k.indices[: len(indices)], indices)
        )


_UPPER_PICK: list[_UpperPick | None] = [None]
"""The pick of the last CSR pattern `upper_triangle` met."""


def _cholespy_factor(k: sp.csc_matrix) -> Factor:
    """A sparse Cholesky factorization of the SPD matrix k with a `.solve(b)` method
    (cholespy, whose solves are about twice as fast as SuperLU's here)."""
    from cholespy import CholeskySolverD, MatrixType

    from fruitcli.fem.solver.c_output import captured_output

    c = k.tocoo()
    # CHOLMOD prints "not positive definite" with C's stdio before cholespy raises
    with captured_output():
        try:
            fac = CholeskySolverD(
                k.shape[0], c.row.astype(np.int32), c.col.astype(np.int32), c.data, MatrixType.COO
            )
        except ValueError:
            raise RuntimeError("CHOLMOD: the matrix is not positive definite") from None

    class _Factor:
        single = False  # exact solves (see continuum_linsolve.factorize)

        @staticmethod
        def solve(b: np.ndarray) -> np.ndarray:
            b = np.ascontiguousarray(b, dtype=float)
            x = np.zeros_like(b)
            fac.solve(b, x)
            return x

    return _Factor()


_cholesky: Callable[[sp.csc_matrix], Factor] | None = _cholespy_factor
"""The positive definite tangent's factorization without PARDISO: cholespy's Cholesky
when installed, else None (SuperLU in symmetric mode)."""
try:
    import cholespy  # noqa: F401
except ImportError:  # optional: SuperLU in symmetric mode instead
    _cholesky = None


class CorotationalBody(Protocol):
    """What `TangentSolver` reads of the corotational model (`corotational_model.Model`):
    its shape gradients (m, 4, 3) 1/mm, Lame constants (kPa), free-dof pattern, springs'
    diagonal over the free dofs (mN/mm) and its tangent, assembled per element or applied."""

    @property
    def grads(self) -> np.ndarray: ...

    @property
    def lame_kpa(self) -> tuple[float, float]: ...

    @property
    def pattern(self) -> CsrPattern: ...

    @property
    def spring_diag(self) -> np.ndarray: ...

    def tangent_blocks(
        self, rot: np.ndarray, f: np.ndarray | None, project: bool = True
    ) -> np.ndarray: ...

    def apply_tangent_free(
        self,
        rot: np.ndarray,
        t_world: np.ndarray | None,
        v_free: np.ndarray,
        rg: np.ndarray | None = None,
    ) -> np.ndarray: ...


class TangentSolver:
    """Solves with the tangent at the rotations given to `update`. Counts its work in
    `stats`: factorizations, cg_iterations, and wall seconds in assembly_s, factor_s,
    update_s (each `update`, with the refreshes it makes), product_s (CG's tangent
    products) and precond_s (CG's triangular solves). `rtol` is the relative residual the
    iterative strategies stop at (Newton sets it per step)."""

    def __init__(self, model: CorotationalBody, method: str = "pcg"):
        if method not in LINEAR_SOLVERS:
            raise SolverError(
                f"[solver].linear_solver: expected one of "
                f"{', '.join(LINEAR_SOLVERS)}, got {method!r}"
            )
        self.model = model
        self.method = method
        self.rot: np.ndarray | None = None  # (m, 3, 3) element rotations of `update`
        self.f: np.ndarray | None = None  # (m, 3, 3) deformation gradients, or None
        self.load_k: sp.csr_matrix | None = None  # follower-pressure stiffness, or None
        self.t_world: np.ndarray | None = None  # rotation-derivative term, or None
        self.rg: np.ndarray | None = None  # rotated shape gradients
        self.factor: Factor | None = None
        self.kind = "warped"
        self.project = False
        self.diag: np.ndarray | None = None  # the tangent's diagonal (`jacobi`)
        self.refresh = False
        self.fresh = False  # the factorization is of the current configuration
        self.rtol = PCG_RELATIVE_TOLERANCE
        # CG's displacement goal (`pcg`; set by Newton per step)
        self.displacement_goal = (0.0, 1.0)
        # read by Newton (`newton.iterate`, 0.0 there without it: no chord steps)
        self.near_tolerance = NEAR_TOLERANCE
        self.newton_c = 0.0  # Newton's merit_new / merit^2, kept across states (rtol)
        # converged (load vector, x, p) for the next state's predictor (`fem_model.Kept`)
        self.history: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        # (dx/dp (n, 3, K), volume compliance (K, K)) at the first state (`predictor`)
        self.sensitivity: tuple[np.ndarray, np.ndarray] | None = None
        self.single = method == "pcg" and SINGLE_PRECISION  # asked of the next factor
        # the last `estimate`: (r, factorizations then, its solve)
        self.estimated: tuple[np.ndarray, int, np.ndarray] | None = None
        self.factor_seconds = 0.0  # Newton's deadline does not look ahead for this one
        pardiso.available()  # MKL loaded here, not inside the first state's time
        threads.one_blas_thread()
        threads.choose_element_threads()
        self.stats: dict[str, float] = {
            "factorizations": 0,
            "cg_iterations": 0,
            "assembly_s": 0.0,
            "factor_s": 0.0,
            "update_s": 0.0,
            "product_s": 0.0,
            "precond_s": 0.0,
        }

    def update(
        self,
        rot: np.ndarray,
        f: np.ndarray | None = None,
        load_stiffness: sp.csr_matrix | None = None,
        project: bool = False,
    ) -> None:
        """Set the current element rotations (m, 3, 3) and deformation gradients (m, 3, 3)
        (without f, the tangent is the warped R K0 R^T), the follower-pressure stiffness
        over the free dofs (anything with `@`, or None) and whether the rotation term is
        projected to positive semi-definite per element."""
        t0 = time.perf_counter()
        self.rot, self.f, self.load_k = rot, f, load_stiffness
        self.project = project
        self.kind = "warped" if f is None else ("projected" if project else "exact")
        self.t_world = None
        self.rg = kernels.rotated_gradients(self.model.grads, np.ascontiguousarray(rot))
        if f is not None:
            lam, mu = self.model.lame_kpa
            self.t_world = np.ascontiguousarray(corotation.skew_stiffness(f, rot, lam, mu, project))
        self.fresh = False
        if self.method == "direct":
            self._factorize(self._assemble(self.kind == "exact"))
        elif self.method == "jacobi":
            self.diag = self._assemble().diagonal()
        elif self.factor is None or self.refresh:
            self._refresh()
        self.stats["update_s"] += time.perf_counter() - t0

    def _refresh(self) -> None:
        """Factorize the positive definite (projected) tangent at the current rotations."""
        if self.f is not None and not self.project:
            lam, mu = self.model.lame_kpa
            keep = self.project, self.load_k
            self.project, self.load_k = True, None
            k = self._assemble(False)
            self.project, self.load_k = keep
        else:
            k = self._assemble(False)
        self._factorize(k)
        self.refresh, self.fresh = False, True

    def _rotations(self) -> np.ndarray:
        """The element rotations `update` set (m, 3, 3)."""
        if self.rot is None:
            raise SolverError("TangentSolver: update() gives the rotations before a solve")
        return self.rot

    def _assemble(self, with_load: bool = True) -> sp.csr_matrix:
        """The tangent assembled over the free dofs (mN/mm), with the follower-pressure
        stiffness when `with_load`; timed."""
        t0 = time.perf_counter()
        m = self.model
        k = m.pattern.assemble(
            m.tangent_blocks(self._rotations(), self.f, self.project), m.spring_diag
        )
        if with_load and self.f is not None and self.load_k is not None:
            k = k + self.load_k
        self.stats["assembly_s"] += time.perf_counter() - t0
        return k

    def _factorize(self, k: sp.csr_matrix) -> None:
        k = k.tocsc()
        t0 = time.perf_counter()
        try:
            if self.method == "direct" and self.kind == "exact":
                self.factor = spla.splu(k, permc_spec="MMD_AT_PLUS_A")  # may be indefinite
            elif USE_PARDISO and pardiso.available():  # kept analysis, refactorized
                previous = self.factor if isinstance(self.factor, pardiso.Pardiso) else None
                self.factor = None
                self.factor = pardiso.factorize_probed(k, upper_triangle(k), previous, self.single)
                # a tangent too ill-conditioned for single precision stays so
                self.single = self.single and getattr(self.factor, "single", False)
                if self.factor is None:  # missed its probe in double precision too
                    self.factor = spla.splu(k, permc_spec="MMD_AT_PLUS_A")
            elif _cholesky is not None:  # positive definite: sparse Cholesky when installed
                self.factor = _cholesky(k)
            else:  # positive definite: symmetric mode, diagonal pivots (about 5x faster)
                self.factor = spla.splu(
                    k,
                    permc_spec="MMD_AT_PLUS_A",
                    diag_pivot_thresh=0.0,
                    options={"SymmetricMode": True},
                )
        except (RuntimeError, pardiso.PardisoError) as exc:  # SuperLU's, PARDISO's
            self.factor = None  # spent: the next update factorizes afresh
            if isinstance(exc, pardiso.PardisoError) and not exc.singular:
                raise SolverError(f"the tangent could not be factorized ({exc})") from None
            raise SolverError(
                f"tangent stiffness is singular ({exc}); is the body held by "
                "[[fixed]], [[jig]] or its rigid modes pinned?"
            ) from None
        if not np.isfinite(self._kept.solve(np.ones(k.shape[0]))).all():
            self.factor = spla.splu(k, permc_spec="MMD_AT_PLUS_A")
        self.stats["factor_s"] += time.perf_counter() - t0
        self.stats["factorizations"] += 1

    @property
    def _kept(self) -> Factor:
        """The kept factor (RuntimeError before the first `update` made one)."""
        if self.factor is None:
            raise RuntimeError("TangentSolver: no factor before the first update")
        return self.factor

    def matvec(self, v_free: np.ndarray) -> np.ndarray:
        """K_t v (matrix-free) for v over the free dofs."""
        t0 = time.perf_counter()
        m = self.model
        out = m.apply_tangent_free(self._rotations(), self.t_world, v_free, self.rg)
        out += m.spring_diag * v_free
        if self.f is not None and self.load_k is not None:
            out = out + self.load_k @ v_free
        self.stats["product_s"] += time.perf_counter() - t0
        return out

    def precondition(self, r: np.ndarray) -> np.ndarray:
        """The kept factorization's solve of r (two triangular solves), timed."""
        t0 = time.perf_counter()
        z = self._kept.solve(r)
        self.stats["precond_s"] += time.perf_counter() - t0
        return z

    def estimate(self, r: np.ndarray) -> np.ndarray | None:
        """The kept factor's solve of r (n_free,): an estimate of K_t^-1 r (mm for r in
        mN), or None without a factor (Jacobi CG, or before the first update)."""
        if self.method == "jacobi" or self.factor is None:
            return None
        z = self.precondition(r)
        self.estimated = (r, int(self.stats["factorizations"]), z)
        return z

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve K_t X = rhs for rhs (n_free,) or (n_free, k)."""
        z0 = kept_estimate(self.estimated, rhs, int(self.stats["factorizations"]))
        if self.method == "direct":
            return self._kept.solve(rhs) if z0 is None else z0
        if z0 is not None:
            return self._solve_one(rhs, z0)
        cols = rhs.reshape(len(rhs), -1)
        out = np.column_stack([self._solve_one(c) for c in cols.T])
        return out.reshape(rhs.shape)

    def _solve_one(self, b: np.ndarray, z0: np.ndarray | None = None) -> np.ndarray:
        if self.method == "jacobi":
            if self.diag is None:
                raise RuntimeError("TangentSolver: no tangent before the first update")
            inv_d = 1.0 / self.diag
            x, its, ok = pcg(
                self.matvec, lambda v: inv_d * v, b, self.rtol, 50 * 20 * PCG_MAX_ITERATIONS
            )
            self.stats["cg_iterations"] += its
            if not ok:
                raise SolverError(
                    f'CG did not converge in {its} iterations (try [solver].linear_solver = "pcg")'
                )
            return x
        limit = PCG_MAX_ITERATIONS if self.fresh else 2 * PCG_REFRESH_ITERATIONS
        x, its, ok = pcg(
            self.matvec, self.precondition, b, self.rtol, limit, z0, self.displacement_goal
        )
        self.stats["cg_iterations"] += its
        if ok:
            # slow but done: keep x, refresh the factorization at the next update
            self.refresh = self.refresh or its > PCG_REFRESH_ITERATIONS
            return x
        if not self.fresh:  # stale preconditioner: refresh it here and retry
            self._refresh()
            x, its, ok = pcg(
                self.matvec,
                self.precondition,
                b,
                self.rtol,
                PCG_MAX_ITERATIONS,
                None,
                self.displacement_goal,
            )
            self.stats["cg_iterations"] += its
        if not ok:
            self.refresh = True
            self.single = self.single and not self.fresh  # a fresh factor failed: double
        return x


def kept_estimate(
    estimated: tuple[np.ndarray, int, np.ndarray] | None, b: np.ndarray, factorizations: int
) -> np.ndarray | None:
    """The solve kept by a solver's `estimate` (r, factorizations then, its solve) when b
    is that same r and no factorization happened since (CG then starts from it instead
    of solving again), else None."""
    if estimated is not None and estimated[0] is b and estimated[1] == factorizations:
        return estimated[2]
    return None


def pcg(
    matvec: Callable[[np.ndarray], np.ndarray],
    precond: Callable[[np.ndarray], np.ndarray],
    b: np.ndarray,
    rtol: float,
    maxiter: int,
    z0: np.ndarray | None = None,
    displacement_goal: tuple[float, float] = (0.0, 1.0),
) -> tuple[np.ndarray, int, bool]:
    """Preconditioned CG from zero for a symmetric operator. Stops at |r| <= rtol |b|;
    with displacement_goal (ztol, zrtol), ztol > 0, also once |r| <= zrtol |b| and the
    preconditioned residual moves no entry by more than ztol (max |precond(r)|: the
    preconditioner's estimate of the error left, mm for a force residual); both count
    as converged.
    Otherwise after `maxiter` iterations or on negative curvature (an indefinite
    tangent); then it returns the last iterate, or the preconditioned residual if there
    is none, which is still a descent direction. z0: precond(b) if already at hand.
    Returns (x, iterations, converged)."""
    ztol, zrtol = displacement_goal
    x = np.zeros_like(b)
    r = b.copy()
    nb = float(np.linalg.norm(b))
    if nb == 0.0:
        return x, 0, True
    z = precond(r) if z0 is None else z0
    p = z.copy()
    rz = float(r @ z)
    for it in range(1, maxiter + 1):
        q = matvec(p)
        pq = float(p @ q)
        if not pq > 0.0:
            return (x if it > 1 else z), it, False
        alpha = rz / pq
        x += alpha * p
        r -= alpha * q
        rn = float(np.linalg.norm(r))
        if rn <= rtol * nb:
            return x, it, True
        z = precond(r)
        if ztol > 0.0 and rn <= zrtol * nb and np.abs(z).max() <= ztol:
            return x, it, True
        rz_new = float(r @ z)
        p = z + (rz_new / rz) * p
        rz = rz_new
    return x, maxiter, False
