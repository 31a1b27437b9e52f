"""PARDISO's analysis made ahead on a thread (`fruitcli.fem.solver.analysis_ahead`): the
next new factor of its pattern takes it and equals to the last bit a factor made without
it; an analysis that does not fit is dropped and the factor made as before."""

import numpy as np
import pytest
import scipy.sparse as sp

from fruitcli.fem.solver import analysis_ahead, continuum_linsolve, pardiso
from fruitcli.fem.solver.linsolve import upper_triangle

pytestmark = pytest.mark.skipif(not pardiso.available(), reason="MKL PARDISO not installed")


def block_matrix(n: int, shift: float = 0.0) -> sp.csr_matrix:
    """The 7-point Laplacian on an n^3 grid with 3 x 3 blocks of ones, plus (3 - shift) I:
    three rows a node with one pattern, as the FEM's tangents (positive definite for
    shift 0, indefinite for shift 4)."""
    one = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    eye = sp.identity(n)
    lap = (
        sp.kron(sp.kron(one, eye), eye)
        + sp.kron(sp.kron(eye, one), eye)
        + sp.kron(sp.kron(eye, eye), one)
    )
    return (sp.kron(lap, np.ones((3, 3))) + (3.0 - shift) * sp.identity(3 * n**3)).tocsr()


@pytest.fixture
def phases(monkeypatch) -> list:
    """PARDISO's phases called from now on (any thread), in order; patterns from 10 rows
    analysed ahead."""
    monkeypatch.setattr(analysis_ahead, "MIN_ROWS", 10)
    called = []
    real = pardiso.Pardiso._factor

    def recorded(self, phase):
        called.append(phase)
        return real(self, phase)

    monkeypatch.setattr(pardiso.Pardiso, "_factor", recorded)
    yield called
    analysis_ahead.taken(None, False)


def test_the_next_factor_of_the_pattern_takes_the_analysis(phases):
    """`start` orders and analyses a pattern on a thread (a second call for the same
    pattern keeps it); the solver's next new factor of a matrix of that pattern takes
    it: only the numerical factorization (phase 22) runs, no analysis of its own (12),
    and its solves equal to the last bit those of a factor made without it, in single
    and double precision."""
    k = block_matrix(5)
    b = np.cos(np.arange(k.shape[0]))
    for single in (False, True):
        pardiso._LAST_ORDER.clear()
        plain = pardiso.factorize_upper(upper_triangle(k), single=single, full=k)
        assert phases == [11, 12]  # the node order, then analysis and factorization
        phases.clear()
        pardiso._LAST_ORDER.clear()
        analysis_ahead.start(k.indptr, k.indices, single)
        begun = analysis_ahead._PENDING[0]
        analysis_ahead.start(k.indptr, k.indices, single)
        assert analysis_ahead._PENDING == [begun]
        fac = continuum_linsolve.factorize(k, None, single)
        assert phases == [11, 11, 22] and not analysis_ahead._PENDING
        assert isinstance(fac, pardiso.Pardiso)
        assert fac.mtype == pardiso.SPD and fac.single == single
        assert np.array_equal(fac.solve(b), plain.solve(b))
        phases.clear()
        fac.free()
        plain.free()


def test_an_analysis_that_does_not_fit_is_dropped(phases):
    """A factor of another pattern, of another precision or asked indefinite makes its
    own analysis and drops the one made ahead; a matrix of the pattern that is not
    positive definite fails on the analysis made ahead and gets the indefinite type.
    Every factor solves to 1e-10; nothing is left pending."""
    k = block_matrix(4)
    cases = [
        (block_matrix(5), False, False, pardiso.SPD),  # another pattern
        (k, True, False, pardiso.SPD),  # single precision asked, double analysed
        (k, False, True, pardiso.SYMMETRIC_INDEFINITE),  # indefinite asked
        (block_matrix(4, shift=4.0), False, False, pardiso.SYMMETRIC_INDEFINITE),
    ]
    for m, single, indefinite, mtype in cases:
        analysis_ahead.start(k.indptr, k.indices, False)
        fac = continuum_linsolve.factorize(m, None, single, indefinite)
        assert not analysis_ahead._PENDING
        assert isinstance(fac, pardiso.Pardiso) and fac.mtype == mtype
        rhs = np.sin(np.arange(m.shape[0]) + 1.0)
        tolerance = 1e-4 if single else 1e-10  # a single-precision factor's own solve
        assert np.linalg.norm(m @ fac.solve(rhs) - rhs) <= tolerance * np.linalg.norm(rhs)
        fac.free()
    assert 12 in phases


def test_a_small_pattern_is_not_analysed_ahead(phases, monkeypatch):
    """Below MIN_ROWS rows nothing starts."""
    monkeypatch.setattr(analysis_ahead, "MIN_ROWS", 10_000)
    k = block_matrix(4)
    analysis_ahead.start(k.indptr, k.indices, False)
    assert not analysis_ahead._PENDING and phases == []
