"""The default install, without the optional extra `pardiso` (MKL): `pardiso.available`
says so instead of failing, and the hyperelastic model's factors are SuperLU's
in symmetric mode (positive definite or not: past a limit point, a collapsing wall),
then SuperLU's general LU, with the results PARDISO gives."""

import glob
import sys

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from fruitcli.errors import SceneError, SolverError
from fruitcli.fem import limits, pressure_check
from fruitcli.fem.solver import continuum_linsolve, pardiso
from fruitcli.fem.solver.options import SolverOptions
from tests.fem.meshing.test_mesh import octant_ball
from tests.fem.test_limits import LIMIT_B_OVER_A_2


@pytest.fixture
def no_pardiso(monkeypatch):
    """PARDISO reported missing, as on a machine without MKL."""
    monkeypatch.setattr(pardiso, "_MISSING", True)


def laplacian(n: int, shift: float = 0.0) -> sp.csc_matrix:
    """The 2D five-point Laplacian on n x n points minus shift * I (indefinite for a shift
    above its smallest eigenvalue, 8 sin^2(pi / (2 (n + 1))))."""
    t = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    k = sp.kron(sp.eye(n), t) + sp.kron(t, sp.eye(n))
    return (k - shift * sp.eye(n * n)).tocsc()


def test_available_is_false_without_mkl_or_pypardiso(monkeypatch):
    monkeypatch.setattr(pardiso, "_FUNCTIONS", None)
    monkeypatch.setattr(pardiso, "_MISSING", False)
    monkeypatch.setattr(glob, "glob", lambda pattern: [])  # no libmkl_rt in the environment
    monkeypatch.setitem(sys.modules, "pypardiso", None)  # `import pypardiso` fails
    assert pardiso.available() is False
    assert pardiso.available() is False  # the answer is kept


def test_factors_without_pardiso(no_pardiso, monkeypatch):
    """Positive definite or not: SuperLU in symmetric mode, not the general LU; each solve
    exact to 1e-10."""
    calls = []
    splu = spla.splu

    def counted(k, **kw):
        calls.append(kw.get("options", {}).get("SymmetricMode", False))
        return splu(k, **kw)

    monkeypatch.setattr(continuum_linsolve.spla, "splu", counted)
    rng = np.random.default_rng(0)
    for shift in (0.0, 1.0):  # positive definite, then indefinite
        k = laplacian(12, shift)
        b = rng.standard_normal(k.shape[0])
        calls.clear()
        fac = continuum_linsolve.factorize(k, single=True, indefinite=shift > 0)
        assert not fac.single and calls == [True]
        assert np.linalg.norm(k @ fac.solve(b) - b) <= 1e-10 * np.linalg.norm(b)


def test_a_singular_tangent_is_one_line_without_pardiso(no_pardiso):
    k = laplacian(6).tolil()
    k[0, :] = 0.0
    k[:, 0] = 0.0
    with pytest.raises(SolverError, match=r"^tangent stiffness is singular \(.*\); is the body"):
        continuum_linsolve.factorize(k.tocsc())


def test_limit_and_refusals_are_the_same_without_pardiso(monkeypatch):
    """The thick sphere's limit pressure followed past its peak (the tangent turns
    indefinite there) and the refusal lines of 28 kPa and -500 kPa: the same with and
    without PARDISO."""
    if not pardiso.available():
        pytest.skip("MKL PARDISO not installed: nothing to compare with")
    key = ["[actuation].pressure_kpa.c"]

    def run():
        model = octant_ball(2, 2, nu=0.49)
        curve = limits.follow(model, 0)
        small = octant_ball(1, 1, nu=0.49)
        lines = []
        for p in (28.0, -500.0):
            with pytest.raises(SceneError) as info:
                pressure_check.check_pressures(
                    small, np.array([[p]]), key, small.make_solver(), SolverOptions(), screen=0.0
                )
            lines.append(str(info.value))
        return model.material.shear_modulus_kpa, curve, lines

    mu, with_mkl, lines_mkl = run()
    monkeypatch.setattr(pardiso, "_MISSING", True)
    _, without, lines = run()
    assert without.end == with_mkl.end == "past the limit point"
    assert without.limit_pressure_kpa == pytest.approx(with_mkl.limit_pressure_kpa, rel=1e-4)
    assert without.limit_pressure_kpa == pytest.approx(LIMIT_B_OVER_A_2 * mu, rel=0.03)
    assert lines == lines_mkl
