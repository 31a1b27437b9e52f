"""MKL PARDISO through `fruitcli.fem.solver.pardiso`: solves against SciPy's, the kept
analysis refactorized in place, the indefinite fallback, no iterative refinement, and
the errors."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from fruitcli.fem.solver import pardiso
from fruitcli.fem.solver.linsolve import upper_triangle

pytestmark = pytest.mark.skipif(not pardiso.available(), reason="MKL PARDISO not installed")


def laplacian(n: int, shift: float = 0.0):
    """The 3D 7-point Laplacian on an n^3 grid minus shift * I (SPD for shift 0)."""
    one = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    eye = sp.identity(n)
    k = (
        sp.kron(sp.kron(one, eye), eye)
        + sp.kron(sp.kron(eye, one), eye)
        + sp.kron(sp.kron(eye, eye), one)
    )
    return (k - shift * sp.identity(n**3)).tocsr()


def test_solves_match_scipy_and_refinement_is_off():
    """One and three right-hand sides agree with SciPy's direct solve to 1e-10, and MKL
    reports no iterative-refinement step (iparm[6])."""
    k = laplacian(9)
    fac = pardiso.factorize_upper(upper_triangle(k))
    assert fac.mtype == pardiso.SPD
    rng = np.random.default_rng(1)
    b = rng.standard_normal(k.shape[0])
    ref = spla.spsolve(k.tocsc(), b)
    assert np.abs(fac.solve(b) - ref).max() < 1e-10 * np.abs(ref).max()
    assert fac.iparm[6] == 0
    bb = rng.standard_normal((k.shape[0], 3))
    x = fac.solve(bb)
    assert x.shape == bb.shape
    assert np.linalg.norm(k @ x - bb) < 1e-10 * np.linalg.norm(bb)


def test_refactor_keeps_the_analysis_for_the_same_pattern():
    """A matrix with the same pattern is refactorized in place (the same object), and
    its solves are those of the new matrix; another pattern gets a new factor."""
    k = laplacian(6)
    fac = pardiso.factorize_upper(upper_triangle(k))
    k2 = (2.5 * k).tocsr()
    again = pardiso.factorize_upper(upper_triangle(k2), fac)
    assert again is fac
    b = np.ones(k.shape[0])
    assert np.linalg.norm(k2 @ again.solve(b) - b) < 1e-10 * np.linalg.norm(b)
    other = pardiso.factorize_upper(upper_triangle(laplacian(5)), fac)
    assert other is not fac and other.n == 125


def test_indefinite_matrix_falls_back_to_the_symmetric_indefinite_type():
    """A symmetric indefinite matrix (the Laplacian shifted past its lowest eigenvalue)
    is factorized as indefinite and solved to 1e-9."""
    k = laplacian(6, shift=1.0)
    fac = pardiso.factorize_upper(upper_triangle(k))
    assert fac.mtype == pardiso.SYMMETRIC_INDEFINITE
    b = np.arange(k.shape[0], dtype=float)
    assert np.linalg.norm(k @ fac.solve(b) - b) < 1e-9 * np.linalg.norm(b)


def test_singular_matrix_is_a_pardiso_error():
    """A matrix with a zero row and column cannot be factorized: PardisoError (a
    SolverError, so the user sees its one line)."""
    k = laplacian(4).tolil()
    k[5, :] = 0.0
    k[:, 5] = 0.0
    with pytest.raises(pardiso.PardisoError):
        pardiso.factorize_upper(upper_triangle(k.tocsr()))


def test_a_failed_refactorization_spends_the_previous_factor():
    """A matrix of the same pattern that cannot be factorized (a row and column of
    explicit zeros) raises PardisoError naming the singular matrix, and the previous
    factor is freed, not left holding a half-written factorization."""
    k = laplacian(4)
    fac = pardiso.factorize_upper(upper_triangle(k))
    bad = upper_triangle(k)
    rows = np.repeat(np.arange(bad.shape[0]), np.diff(bad.indptr))
    bad.data[(rows == 5) | (bad.indices == 5)] = 0.0
    assert bad.nnz == upper_triangle(k).nnz  # the same pattern: a refactorization
    with pytest.raises(pardiso.PardisoError) as err:
        pardiso.factorize_upper(bad, fac)
    assert err.value.singular and "singular" in str(err.value)
    assert not fac._alive


def test_single_precision_factor_solves_to_single_precision_and_refactors_in_kind():
    """A single-precision factor (iparm[27] = 1) solves the Laplacian to within 1e-5
    relative (float32's 6e-8 times the factor's condition), returns float64, keeps its
    analysis for a matrix of the same pattern in the same precision and is replaced by
    a new factor when double precision is asked."""
    k = laplacian(8)
    fac = pardiso.factorize_upper(upper_triangle(k), single=True)
    assert fac.single and fac.iparm[27] == 1 and fac.data.dtype == np.float32
    b = np.random.default_rng(3).standard_normal(k.shape[0])
    x = fac.solve(b)
    assert x.dtype == np.float64
    residual = np.linalg.norm(k @ x - b) / np.linalg.norm(b)
    assert 1e-12 < residual < 1e-5  # not exact: the arithmetic is single precision
    k2 = (3.0 * k).tocsr()
    again = pardiso.factorize_upper(upper_triangle(k2), fac, single=True)
    assert again is fac
    assert np.linalg.norm(k2 @ again.solve(b) - b) < 1e-5 * np.linalg.norm(b)
    double = pardiso.factorize_upper(upper_triangle(k2), again)
    assert double is not again and not double.single and not again._alive
    assert np.linalg.norm(k2 @ double.solve(b) - b) < 1e-10 * np.linalg.norm(b)


def counting(monkeypatch) -> list:
    """The mtypes of the new PARDISO factors (analyses) tried from now on, in order."""
    tried = []

    class Counted(pardiso.Pardiso):
        def __init__(self, upper, mtype=pardiso.SPD, single=False, *args, **kwargs):
            tried.append(mtype)
            super().__init__(upper, mtype, single, *args, **kwargs)

    monkeypatch.setattr(pardiso, "Pardiso", Counted)
    return tried


def test_indefinite_hint_skips_the_positive_definite_analysis(monkeypatch):
    """With `indefinite`, an indefinite matrix costs one analysis (not a failed positive
    definite one first) and a positive definite one is factored as indefinite, both
    solved to 1e-9."""
    tried = counting(monkeypatch)
    b = np.arange(216, dtype=float)
    for shift in (1.0, 0.0):
        k = laplacian(6, shift=shift)
        fac = pardiso.factorize_upper(upper_triangle(k), indefinite=True)
        assert fac.mtype == pardiso.SYMMETRIC_INDEFINITE
        assert np.linalg.norm(k @ fac.solve(b) - b) < 1e-9 * np.linalg.norm(b)
    assert tried == [pardiso.SYMMETRIC_INDEFINITE] * 2
    spd = pardiso.factorize_upper(upper_triangle(k))  # a positive definite analysis
    assert spd.mtype == pardiso.SPD and tried[-1] == pardiso.SPD
    hinted = pardiso.factorize_upper(upper_triangle(k), spd, indefinite=True)
    assert hinted.mtype == pardiso.SYMMETRIC_INDEFINITE and not spd._alive
    assert tried[-1] == pardiso.SYMMETRIC_INDEFINITE


def test_a_positive_definite_refactorization_that_meets_a_negative_pivot_goes_indefinite(
    monkeypatch,
):
    """A positive definite factor refactorized with an indefinite matrix of its pattern
    (its zero-pivot error, -4) is replaced by one new indefinite analysis, not a
    positive definite one first; an indefinite previous factor's replacement (another
    pattern) is indefinite at once too."""
    k = laplacian(6)
    fac = pardiso.factorize_upper(upper_triangle(k))
    tried = counting(monkeypatch)
    shifted = laplacian(6, shift=1.0)
    again = pardiso.factorize_upper(upper_triangle(shifted), fac)
    assert again.mtype == pardiso.SYMMETRIC_INDEFINITE and not fac._alive
    b = np.ones(216)
    assert np.linalg.norm(shifted @ again.solve(b) - b) < 1e-9 * np.linalg.norm(b)
    other = pardiso.factorize_upper(upper_triangle(laplacian(5)), again)
    assert other.mtype == pardiso.SYMMETRIC_INDEFINITE
    assert tried == [pardiso.SYMMETRIC_INDEFINITE] * 2


def test_a_stale_indefinite_factor_leaves_the_columns_after_the_first_failure():
    """GMRES on a tangent whose kept indefinite factor is stale (the shifted Laplacian's,
    the tangent that Laplacian plus a random diagonal of 0-100; 31-32 iterations with the
    stale factor): with `stale`, the second column is not tried once the first fails
    within the limit; without it both are. The solver's `_solve_columns` (24 with the
    stale factor) then refactors once and solves both to CG's tolerance."""
    from fruitcli.fem.solver.continuum_linsolve import ContinuumSolver, factorize

    old = laplacian(8, shift=1.0)
    rng = np.random.default_rng(3)
    new = (old + sp.diags(rng.uniform(0.0, 100.0, old.shape[0]))).tocsr()
    solver = ContinuumSolver(None)
    solver.k, solver.single, solver.indefinite = new, False, True
    solver.factor = factorize(old, indefinite=True)
    b = rng.standard_normal((old.shape[0], 2))
    _, its, ok = solver._krylov(b, 3, stale=True)
    assert its.tolist() == [3, 0] and not ok.any()
    _, its, ok = solver._krylov(b, 3)
    assert its.tolist() == [3, 3] and not ok.any()
    x = solver._solve_columns(b)
    assert solver.stats["factorizations"] == 1
    residual = np.linalg.norm(new @ x - b, axis=0) / np.linalg.norm(b, axis=0)
    assert np.all(residual <= solver.rtol)
