"""The single-precision preconditioner (`pardiso.factorize_probed`, used by both
solvers): CG still solves to the asked tolerance, an ill-conditioned tangent falls back
to double precision for good, and a state's nodes agree with the double-precision
factor's to the solver's tolerance."""

import numpy as np
import pytest
import scipy.sparse as sp

from fruitcli.fem.solver import continuum_linsolve, linsolve, pardiso

pytestmark = pytest.mark.skipif(not pardiso.available(), reason="MKL PARDISO not installed")


def chain(n: int):
    """A 1D chain of unit springs fixed at one end (condition number about n^2)."""
    k = np.ones(n)
    main = k + np.append(k[1:], 0.0)
    return sp.diags([-k[1:], main, -k[1:]], [-1, 0, 1]).tocsr()


class _Model:
    """The solver only asks its model for the tangent."""

    def __init__(self, k):
        self.k = k

    def tangent(self, x, project=False):
        return self.k


def test_fresh_single_factor_still_solves_to_the_asked_tolerance():
    """A fresh single-precision factor is not taken as exact: CG on the tangent reaches
    the asked relative residual (1e-10), beyond what the factor's solve alone gives."""
    k = chain(400) + 1e-3 * sp.identity(400)
    solver = continuum_linsolve.ContinuumSolver(_Model(k.tocsr()))
    solver.update(np.zeros((1, 3)))
    assert solver.factor.single and solver.fresh
    b = np.cos(np.arange(400.0))
    only_factor = np.linalg.norm(k @ solver.factor.solve(b) - b) / np.linalg.norm(b)
    solver.rtol = 1e-10
    x = solver.solve(b)
    assert only_factor > 1e-8
    assert np.linalg.norm(k @ x - b) <= 1e-10 * np.linalg.norm(b)


def pairs(m: int, soft: float):
    """m uncoupled pairs [[1, soft - 1], [soft - 1, 1]]: the vector of ones is the soft
    eigenvector (eigenvalue `soft`), so the factor's probe meets the worst conditioning."""
    block = np.array([[1.0, soft - 1.0], [soft - 1.0, 1.0]])
    return sp.kron(sp.identity(m), block).tocsr()


@pytest.mark.parametrize("soft", [1e-7, 1e-9])
def test_ill_conditioned_tangent_falls_back_to_double_precision_for_good(soft):
    """A tangent single precision cannot factorize well gets a double-precision factor,
    and later refreshes ask for double precision at once: with soft = 1e-7, 1 - soft is
    rounded by 19 % of soft in float32, so the probe's residual misses SINGLE_PROBE; with
    1e-9 it rounds to 1 and the single-precision matrix is singular (PardisoError)."""
    k = pairs(100, soft)
    solver = continuum_linsolve.ContinuumSolver(_Model(k))
    solver.update(np.zeros((1, 3)))
    assert not solver.factor.single and not solver.single
    b = np.ones(200)
    assert np.linalg.norm(k @ solver.solve(b) - b) <= 1e-6 * np.linalg.norm(b)
    solver.refresh = True
    solver.update(np.zeros((1, 3)))
    assert not solver.factor.single


def hollow_cube_states(
    monkeypatch, element: str, single: bool, chord: bool = True, tolerance: float = 1e-8
):
    """A hollow cube (linear corotational, or quadratic neo-Hookean; nu = 0.49) under
    6 kPa, then 9 kPa from there, with the kept factor in single or double precision,
    with or without Newton's chord steps; (nodes of both states, whether the last factor
    was single precision, tangent updates over Newton steps)."""
    from fruitcli.fem.continuum import ContinuumModel
    from fruitcli.fem.corotational_model import Model
    from fruitcli.fem.elements.quadratic import quadratic_mesh
    from fruitcli.fem.materials.build import material
    from fruitcli.fem.meshing.grid import structured_box_with_cavity
    from fruitcli.fem.solver import linsolve
    from fruitcli.fem.solver.options import SolverOptions
    from fruitcli.fem.solver.state import solve_state
    from fruitcli.fem.state_load import Load

    monkeypatch.setattr(linsolve, "SINGLE_PRECISION", single)
    nodes, tets, cav = structured_box_with_cavity(
        [0, 0, 0], [12, 12, 12], (6, 6, 3), [3, 3, 3], [9, 9, 9]
    )
    fixed = np.flatnonzero(nodes[:, 2] == 0.0)
    if element == "p1":
        m = Model.from_arrays(nodes, tets, 100.0, 0.49, chambers={"c": cav}, fixed_nodes=fixed)
    else:
        nodes, conn, walls = quadratic_mesh(nodes, tets, [cav])
        m = ContinuumModel.from_arrays(
            nodes,
            conn,
            material("neo-hookean", 100.0, 0.49),
            "p2",
            chambers={"c": walls[0]},
            fixed_nodes=fixed,
        )
    solver = m.make_solver("pcg")
    if not chord:
        solver.near_tolerance = 0.0
    updates = []
    update = solver.update
    solver.update = lambda *args, **kwargs: updates.append(1) or update(*args, **kwargs)
    options = SolverOptions(tolerance=tolerance)
    a = solve_state(m, Load.pressures([6.0]), solver=solver, options=options)
    b = solve_state(
        m,
        Load.pressures([9.0]),
        x_start=a.x,
        load_start=Load.pressures([6.0]),
        pressure_start=a.pressure_kpa,
        solver=solver,
        options=options,
    )
    return (a.x, b.x), solver.factor.single, len(updates) / (a.iterations + b.iterations)


@pytest.mark.parametrize("element", ["p1", "p2"])
def test_states_agree_with_the_double_precision_factor_to_the_tolerance(monkeypatch, element):
    """The preconditioner's precision changes CG's path, not the equilibrium: two
    inflation states of a hollow cube agree to 1e-6 mm (tolerance 1e-8 on a 12 mm cube),
    on both solvers."""
    single, was_single, _ = hollow_cube_states(monkeypatch, element, True)
    double, was_double, _ = hollow_cube_states(monkeypatch, element, False)
    assert was_single and not was_double
    for xs, xd in zip(single, double, strict=True):
        assert np.abs(xs - xd).max() < 1e-6
    assert np.abs(single[1] - single[0]).max() > 0.1  # the states did move


def test_hyperelastic_chord_steps_reach_the_same_states(monkeypatch):
    """Near the tolerance Newton keeps the quadratic element's tangent (a chord step,
    `near_tolerance`; tolerance 1e-6, so that a step ends within 30 times it): fewer
    tangent updates than Newton steps, and the same two states as without chord steps
    to 1e-6 mm."""
    chord, _, updates_chord = hollow_cube_states(monkeypatch, "p2", True, tolerance=1e-6)
    plain, _, updates_plain = hollow_cube_states(
        monkeypatch, "p2", True, chord=False, tolerance=1e-6
    )
    assert updates_chord < 1.0 <= updates_plain
    for xc, xp in zip(chord, plain, strict=True):
        assert np.abs(xc - xp).max() < 1e-6


def test_fresh_single_factor_that_fails_cg_is_replaced_by_double(monkeypatch):
    """When CG on a fresh single-precision factor does not converge within its limit
    (forced here: no iteration allowed), the solver refactorizes in double precision,
    keeps double precision for later factors, and the solve is exact."""
    monkeypatch.setattr(continuum_linsolve, "PCG_REFRESH_ITERATIONS", 0)
    k = chain(300) + 1e-3 * sp.identity(300)
    solver = continuum_linsolve.ContinuumSolver(_Model(k.tocsr()))
    solver.update(np.zeros((1, 3)))
    assert solver.factor.single and solver.fresh
    b = np.sin(np.arange(300.0))
    solver.rtol = 1e-10
    x = solver.solve(b)
    assert not solver.single and not solver.factor.single
    assert np.linalg.norm(k @ x - b) <= 1e-10 * np.linalg.norm(b)


def test_columns_in_lockstep_are_each_columns_own_cg():
    """`pcg_columns` gives each column the iterate, iteration count and verdict of CG on
    that column alone: converged columns (one of them 1e-3 times smaller), a zero
    column, and negative curvature on an indefinite matrix."""
    n = 300
    k = (chain(n) + 1e-2 * sp.identity(n)).tocsr()
    d = k.diagonal()

    def jacobi(r):
        return (r.T / d).T

    rng = np.random.default_rng(0)
    b = rng.standard_normal((n, 3))
    b[:, 1] *= 1e-3
    b[:, 2] = 0.0
    for matrix in (k, (k - 0.5 * sp.identity(n)).tocsr()):
        x, its, ok = continuum_linsolve.pcg_columns(matrix.__matmul__, jacobi, b, 1e-9, 400)
        for j in range(3):
            xj, its_j, ok_j = linsolve.pcg(matrix.__matmul__, jacobi, b[:, j], 1e-9, 400)
            assert (its[j], ok[j]) == (its_j, ok_j)
            assert np.abs(x[:, j] - xj).max() <= 1e-8 * max(np.abs(xj).max(), 1e-300)


def test_gmres_solves_an_indefinite_system_with_an_indefinite_preconditioner():
    """`gmres_right` (the solver's Krylov method once its factor is symmetric
    indefinite, past a limit point) reaches the asked residual on an indefinite matrix
    preconditioned by a nearby indefinite one, in one step with the exact inverse, and
    reports a residual it did not reach as not converged."""
    import scipy.sparse.linalg as spla

    n = 300
    k = (chain(n) - 0.05 * sp.identity(n)).tocsc()
    assert np.linalg.eigvalsh(k.toarray()).min() < 0 < np.linalg.eigvalsh(k.toarray()).max()
    near = spla.splu((k + 1e-3 * sp.diags(np.cos(np.arange(n)))).tocsc())
    b = np.sin(np.arange(n) + 1.0)
    for rtol in (1e-4, 1e-10):
        x, its, ok = continuum_linsolve.gmres_right(k.__matmul__, near.solve, b, rtol, 60)
        assert ok and np.linalg.norm(k @ x - b) <= 1.01 * rtol * np.linalg.norm(b)
    exact = spla.splu(k)
    x, its, ok = continuum_linsolve.gmres_right(k.__matmul__, exact.solve, b, 1e-10, 60)
    assert ok and its == 1
    x, its, ok = continuum_linsolve.gmres_right(k.__matmul__, lambda v: v, b, 1e-10, 3)
    assert not ok and its == 3


def test_a_stale_indefinite_factor_takes_gmres_a_definite_one_cg(monkeypatch):
    """Past a limit point (negative pivots in the kept symmetric indefinite factor) the
    solver's Krylov method is GMRES, and it reaches the asked residual with a stale
    factor on an indefinite tangent, one column or two; a positive definite tangent
    factored as indefinite keeps CG."""
    calls = []
    real = continuum_linsolve.gmres_right

    def counted(*args):
        calls.append(1)
        return real(*args)

    monkeypatch.setattr(continuum_linsolve, "gmres_right", counted)
    n = 300
    old = (chain(n) - 0.05 * sp.identity(n)).tocsr()
    model = _Model(old)
    solver = continuum_linsolve.ContinuumSolver(model)
    solver.indefinite = True
    solver.update(np.zeros((1, 3)))
    assert solver.factor.mtype == pardiso.SYMMETRIC_INDEFINITE and solver.factor.iparm[22] > 0
    model.k = (old + 1e-3 * sp.diags(np.cos(np.arange(n)))).tocsr()  # the tangent moved on
    solver.update(np.zeros((1, 3)))
    assert not solver.fresh
    solver.rtol = 1e-8
    b = np.column_stack([np.sin(np.arange(n) + 1.0), np.cos(np.arange(n))])
    for rhs in (b[:, 0], b):
        x = solver.solve(rhs)
        assert np.linalg.norm(model.k @ x - rhs) <= 1.01e-8 * np.linalg.norm(rhs)
    assert len(calls) == 3
    spd = _Model((chain(n) + 1e-3 * sp.identity(n)).tocsr())
    solver = continuum_linsolve.ContinuumSolver(spd)
    solver.indefinite = True
    solver.update(np.zeros((1, 3)))
    spd.k = (spd.k + 1e-4 * sp.identity(n)).tocsr()
    solver.update(np.zeros((1, 3)))
    solver.solve(b)
    assert solver.factor.mtype == pardiso.SYMMETRIC_INDEFINITE and len(calls) == 3
