"""Solver behaviour on small structured bodies (no gmsh): a pad bent over by jig springs
(the touchpad scene in miniature), a free hollow body under pressure, state sequences
continued from the previous states, and the SuperLU fallback without cholespy."""

import numpy as np
import pytest

from fruitcli.fem.corotational_model import Model
from fruitcli.fem.loads.springs import Jig, nodes_in_box
from fruitcli.fem.meshing.grid import structured_box, structured_box_with_cavity
from fruitcli.fem.solver import linsolve
from fruitcli.fem.solver.linsolve import TangentSolver
from fruitcli.fem.solver.options import SolverOptions
from fruitcli.fem.solver.state import solve_state
from fruitcli.fem.state_load import Load


def hollow_box(nu: float) -> Model:
    """A 12 mm cube of 6 x 6 x 6 cells with a 4 mm cubic cavity "c" in its middle, E = 100
    kPa, Poisson's ratio nu, its bottom face fixed."""
    nodes, tets, cav = structured_box_with_cavity(
        [0, 0, 0], [12, 12, 12], (6, 6, 6), [4, 4, 4], [8, 8, 8]
    )
    return Model.from_arrays(
        nodes, tets, 100.0, nu, chambers={"c": cav}, fixed_nodes=np.flatnonzero(nodes[:, 2] == 0.0)
    )


def bent_pad(steps=8, solver="pcg"):
    """A 40 x 16 x 2 mm pad, left strip fixed, right strip carried 180 degrees over the
    y axis through a pivot 7.4 mm above the mid-plane (the touchpad scene's bend)."""
    nodes, tets = structured_box([-20, -8, 0], [20, 8, 2], (20, 8, 1))
    fixed = nodes_in_box(nodes, [-21, -9, -1, -12.5, 9, 3])
    region = nodes_in_box(nodes, [12.5, -9, -1, 21, 9, 3])
    jig = Jig(region, 1e4, rotate_deg=-180.0, axis=(0.0, 1.0, 0.0), pivot_mm=(0.0, 0.0, 8.4))
    m = Model.from_arrays(nodes, tets, 100.0, 0.45, fixed_nodes=fixed, jigs=[jig])
    res = solve_state(
        m,
        Load.pressures([], gravity=0.0, jig=1.0),
        options=SolverOptions(tolerance=1e-6, load_steps=steps, linear_solver=solver),
    )
    return m, jig, region, res


def test_pad_bent_over_by_jig_springs_converges():
    """The bend converges at tolerance 1e-6 without subdivision and without inverted
    tets; the carried strip lies upside down on its target (within 0.05 mm: the springs
    are 10 N/mm against a 100 kPa pad) above the fixed one."""
    m, jig, region, res = bent_pad()
    assert res.residual <= 1e-6 and res.subdivisions == 0
    assert 0.05 < res.min_det_f < 1.0
    target = jig.targets(m.rest)
    assert np.abs(res.x[region] - target).max() < 0.05
    assert res.x[region, 2].min() > 14.0  # carried over: z from 16.8 - z_rest


def test_free_hollow_body_under_pressure_has_no_support_reactions():
    """A free hollow cube (3-2-1 support only) under 4 kPa: converges, and the support
    carries nothing (the pressure is self-equilibrated): the force balance holds at the
    pinned dofs too (1e-6 of the pressure force). Its cavity grows as much as with the
    base fixed, within 30 %."""
    nodes, tets, cav = structured_box_with_cavity(
        [0, 0, 0], [12, 12, 12], (6, 6, 6), [4, 4, 4], [8, 8, 8]
    )
    m = Model.from_arrays(nodes, tets, 100.0, 0.3, chambers={"c": cav})
    assert len(m.pinned_dofs) == 6 and any("3-2-1" in n for n in m.notes)
    res = solve_state(m, Load.pressures([4.0]))
    assert res.residual <= 1e-6 and res.subdivisions == 0
    f_ext = m.external_forces(res.x, res.pressure_kpa, Load.pressures([4.0]))
    f_int = m.internal_forces(res.x, m.rotations(res.x)[0])
    reaction = (f_int - f_ext).reshape(-1)[m.pinned_dofs]
    assert np.abs(reaction).max() < 1e-6 * np.abs(f_ext).sum()
    fixed = Model.from_arrays(
        nodes, tets, 100.0, 0.3, chambers={"c": cav}, fixed_nodes=np.flatnonzero(nodes[:, 2] == 0.0)
    )
    growth_fixed = solve_state(fixed, Load.pressures([4.0])).chamber_volume_mm3[0] - 64.0
    assert res.chamber_volume_mm3[0] - 64.0 == pytest.approx(growth_fixed, rel=0.3)


def test_state_sequence_continued_from_previous_states_matches_fresh_solves():
    """Pressures 5..40 kPa solved one after the other with one solver (kept factorization,
    secant start from the previous states) give the fresh solution of each state (1e-5
    of the displacement) in no more Newton iterations than without the secant start
    (here 22 against 24 in all)."""
    m = hollow_box(0.3)
    opts = SolverOptions(tolerance=1e-8)
    totals = []
    for secant in (True, False):
        solver = TangentSolver(m)
        x = p = prev = None
        total = 0
        for pk in np.arange(1, 9) * 5.0:
            load = Load.pressures([pk])
            if not secant:
                solver.history.clear()
            res = solve_state(
                m, load, x_start=x, load_start=prev, pressure_start=p, options=opts, solver=solver
            )
            if secant and pk in (10.0, 40.0):
                fresh = solve_state(m, load, options=opts)
                scale = np.abs(fresh.displacement_mm).max()
                assert np.abs(res.x - fresh.x).max() < 1e-5 * scale
            x, p, prev = res.x, res.pressure_kpa, load
            total += res.iterations
        totals.append(total)
    assert totals[0] < totals[1]


def second_state(m, a: Load, b: Load, opts, keep: bool):
    """(the first state under a, `sensitivity_guess`'s start for b, the state under b
    from the first) on a fresh solver; without `keep`, the first state's sensitivity is
    dropped (no guess)."""
    from fruitcli.fem.solver.predictor import sensitivity_guess

    solver = TangentSolver(m)
    first = solve_state(m, a, options=opts, solver=solver)
    assert solver.sensitivity is not None
    if not keep:
        solver.sensitivity = None
    guess = sensitivity_guess(solver, first.x, b)
    assert (guess is not None) == keep
    res = solve_state(
        m,
        b,
        x_start=first.x,
        load_start=a,
        pressure_start=first.pressure_kpa,
        options=opts,
        solver=solver,
    )
    return first, guess, res


def test_first_state_sensitivity_starts_the_next_state_to_first_order():
    """After the first state (4 kPa) the solver keeps dx/dp = K^-1 H^T; the next state
    (5 kPa), whose history is too short for the secant, starts from x + dx/dp dp: within
    3 % of the displacement between the two states (the start at the previous state is
    100 % off), and it converges in no more Newton iterations than from there, to the
    same solution (1e-6 of the displacement)."""
    m = hollow_box(0.45)
    opts = SolverOptions(tolerance=1e-8)
    a, b = Load.pressures([4.0]), Load.pressures([5.0])
    results = []
    for keep in (True, False):
        first, guess, res = second_state(m, a, b, opts, keep)
        results.append(res)
        if keep:
            step = np.abs(res.x - first.x).max()
            assert np.abs(guess[0] - res.x).max() < 0.03 * step
    assert results[0].iterations <= results[1].iterations
    scale = np.abs(results[1].displacement_mm).max()
    assert np.abs(results[0].x - results[1].x).max() < 1e-6 * scale


def test_first_state_sensitivity_starts_a_volume_change_to_first_order():
    """The same under volume control (the samples of a pressure-volume curve): after the
    first state (cavity grown 40 mm^3) the next starts from x + dx/dp dp with dp = dV / C,
    C = H dx/dp the kept compliance. 10 mm^3 further: the start within 3 % of the
    displacement between the two states and its pressure within 10 % of the pressure
    change; 5 mm^3 further, both errors half as large (a first-order guess), and fewer
    Newton iterations than from the previous state."""
    from fruitcli.fem.curve_start import chamber_load

    m = hollow_box(0.45)
    opts = SolverOptions(tolerance=1e-10)
    a = chamber_load(m, 0, 40.0)
    errors, iterations = [], []
    for further, keep in ((10.0, True), (5.0, True), (5.0, False)):
        first, guess, res = second_state(m, a, chamber_load(m, 0, 40.0 + further), opts, keep)
        iterations.append(res.iterations)
        if keep:
            step = np.abs(res.x - first.x).max()
            dp = res.pressure_kpa[0] - first.pressure_kpa[0]
            errors.append(
                (np.abs(guess[0] - res.x).max() / step, abs(guess[1][0] - res.pressure_kpa[0]) / dp)
            )
    assert errors[0][0] < 0.03 and errors[0][1] < 0.10
    assert np.allclose(np.divide(errors[1], errors[0]), 0.5, atol=0.05)
    assert iterations[1] < iterations[2]


@pytest.mark.parametrize("fallback", ["cholespy", "superlu"])
def test_fallbacks_without_pardiso(monkeypatch, fallback):
    """Without MKL PARDISO the kept factorization is cholespy's, and without cholespy
    SuperLU's: the same bend result."""
    _, _, _, ref = bent_pad(steps=6)
    monkeypatch.setattr(linsolve, "USE_PARDISO", False)
    if fallback == "superlu":
        monkeypatch.setattr(linsolve, "_cholesky", None)
    _, _, _, res = bent_pad(steps=6)
    assert res.residual <= 1e-6
    assert np.abs(res.x - ref.x).max() < 1e-4


def test_history_guess_is_exact_for_a_quadratic_response_on_a_planar_load_path():
    """Breathing-like loads (phase-shifted sinusoids: an ellipse in a plane of the
    pressure space): with 6 kept states the guess reproduces any response quadratic in
    the pressures; with 3 it falls back to the first-order weights."""
    from fruitcli.fem.solver.predictor import HISTORY_STATES, history_guess, load_vector

    rng = np.random.default_rng(3)
    a, b, c = (
        rng.standard_normal((4, 3, 3, 3)),
        rng.standard_normal((4, 3, 3)),
        rng.standard_normal((4, 3)),
    )

    def response(pk):  # (4, 3) "x", quadratic in the 3 pressures
        return c + b @ pk + np.einsum("nkij,i,j->nk", a, pk, pk)

    theta = 2 * np.pi * np.arange(8) / 12
    loads = [Load.pressures(6 - 6 * np.cos(t + np.array([0.0, 2.1, 4.2]))) for t in theta]
    hist = [(load_vector(ld), response(ld.pressure_kpa), ld.pressure_kpa) for ld in loads[:7]]
    hist = hist[-HISTORY_STATES:]
    x, p = history_guess(hist, hist[-1][1], loads[7])
    np.testing.assert_allclose(x, response(loads[7].pressure_kpa), atol=1e-8)
    np.testing.assert_allclose(p, loads[7].pressure_kpa, atol=1e-10)
    x3, _ = history_guess(hist[-3:], hist[-1][1], loads[7])  # affine only
    assert np.abs(x3 - response(loads[7].pressure_kpa)).max() > 1e-3


def test_history_guess_is_exact_for_a_cubic_response_given_enough_states():
    """The same path with a response cubic in the pressures: 8 kept states leave weights
    free after the first and second moments, and matching the third makes the guess
    exact (1e-8); 6 kept states only reach the second order (off by more than 1e-3)."""
    from fruitcli.fem.solver.predictor import history_guess, load_vector

    rng = np.random.default_rng(5)
    a, b = rng.standard_normal((4, 3, 3, 3, 3)), rng.standard_normal((4, 3, 3))

    def response(pk):  # (4, 3), cubic in the 3 pressures (scaled to stay O(1))
        q = pk / 12.0
        return b @ q + np.einsum("nkijl,i,j,l->nk", a, q, q, q)

    theta = 2 * np.pi * np.arange(9) / 12
    loads = [Load.pressures(6 - 6 * np.cos(t + np.array([0.0, 2.1, 4.2]))) for t in theta]
    hist = [(load_vector(ld), response(ld.pressure_kpa), ld.pressure_kpa) for ld in loads[:8]]
    exact = response(loads[8].pressure_kpa)
    x, _ = history_guess(hist, hist[-1][1], loads[8])
    np.testing.assert_allclose(x, exact, atol=1e-8)
    x6, _ = history_guess(hist[-6:], hist[-1][1], loads[8])
    assert np.abs(x6 - exact).max() > 1e-3


def test_history_keeps_one_state_per_load():
    """A repeated load (an animation closing its cycle on its first state) replaces its
    earlier state in the kept history instead of taking a second slot; beyond
    HISTORY_STATES the oldest goes."""
    from fruitcli.fem.solver.predictor import HISTORY_STATES, load_vector, remember

    hist = []
    for i, pk in enumerate((1.0, 2.0, 3.0, 1.0, 4.0)):
        hist = remember(hist, load_vector(Load.pressures([pk])), np.full((2, 3), i), np.array([pk]))
    assert [h[2][0] for h in hist] == [2.0, 3.0, 1.0, 4.0]
    assert hist[2][1][0, 0] == 3  # the repeated load keeps its newest state
    for pk in range(5, 5 + HISTORY_STATES):
        hist = remember(
            hist, load_vector(Load.pressures([pk])), np.zeros((2, 3)), np.array([float(pk)])
        )
    assert [h[2][0] for h in hist] == [float(pk) for pk in range(5, 5 + HISTORY_STATES)]


def test_chord_steps_near_the_tolerance_keep_the_results_of_the_reference_path(monkeypatch):
    """A pressure cycle solved from state to state with the kept factorization (nu =
    0.49, tolerance 1e-6): with the chord steps near the tolerance (the TangentSolver's
    default) chord steps are taken, no state needs more Newton iterations than on the
    reference path (no chord step), and every state
    equals a fresh direct solve at tolerance 1e-11 to 1e-6 of the largest displacement
    on both paths."""
    from fruitcli.fem.solver import newton

    m = hollow_box(0.49)
    pressures = [2.0, 5.0, 8.0, 10.0, 8.0, 5.0, 2.0, 0.5, 3.0, 7.0]
    ref = [
        solve_state(
            m, Load.pressures([pk]), options=SolverOptions(tolerance=1e-11, linear_solver="direct")
        )
        for pk in pressures
    ]
    scale = max(np.abs(r.displacement_mm).max() for r in ref)
    chords = []
    direction = newton.NewtonStep.direction

    def spy(self, *args, keep_tangent=False):
        chords.append(keep_tangent)
        return direction(self, *args, keep_tangent=keep_tangent)

    monkeypatch.setattr(newton.NewtonStep, "direction", spy)
    iterations = {}
    for near in (TangentSolver(m).near_tolerance, 0.0):
        solver = TangentSolver(m)
        solver.near_tolerance = near
        chords.clear()
        x = p = prev = None
        its = []
        for pk, fresh in zip(pressures, ref, strict=True):
            load = Load.pressures([pk])
            res = solve_state(
                m,
                load,
                x_start=x,
                load_start=prev,
                pressure_start=p,
                options=SolverOptions(tolerance=1e-6),
                solver=solver,
            )
            assert res.residual <= 1e-6
            assert np.abs(res.x - fresh.x).max() <= 1e-6 * scale
            its.append(res.iterations)
            x, p, prev = res.x, res.pressure_kpa, load
        iterations[near > 0] = its
        assert any(chords) == (near > 0)
    assert all(a <= b for a, b in zip(iterations[True], iterations[False], strict=True))


def test_first_state_at_rest_keeps_no_sensitivity_and_the_next_solves():
    """A first state that needs no Newton step (zero pressure from the rest positions,
    as a scene starting at rest twice) leaves no dx/dp (the solver has no tangent yet)
    and no error; the next state converges."""
    m = hollow_box(0.45)
    solver = TangentSolver(m)
    rest = solve_state(m, Load.pressures([0.0]), x_start=m.rest.copy(), solver=solver)
    assert rest.iterations == 0 and solver.sensitivity is None
    res = solve_state(
        m,
        Load.pressures([3.0]),
        x_start=rest.x,
        load_start=Load.pressures([0.0]),
        pressure_start=rest.pressure_kpa,
        solver=solver,
    )
    assert res.residual <= 1e-6


def test_a_repeated_load_within_the_kept_states_starts_at_its_own_state():
    """A cycle of 13 distinct pressures (the breathing's length) solved twice with one
    solver: the history holds all 13 (HISTORY_STATES >= 13), and each state of the
    second cycle starts at its own state of the first, so it needs no Newton step and
    returns those nodes."""
    from fruitcli.fem.solver.predictor import HISTORY_STATES

    assert HISTORY_STATES >= 13
    nodes, tets, cav = structured_box_with_cavity(
        [0, 0, 0], [12, 12, 12], (5, 5, 5), [4, 4, 4], [8, 8, 8]
    )
    m = Model.from_arrays(
        nodes,
        tets,
        100.0,
        0.45,
        chambers={"c": cav},
        fixed_nodes=np.flatnonzero(nodes[:, 2] == 0.0),
    )
    solver = TangentSolver(m)
    cycle = [Load.pressures([1.0 + 0.8 * k]) for k in range(13)]
    x = p = prev = None
    first = []
    for i, load in enumerate(cycle + cycle[1:]):
        res = solve_state(
            m,
            load,
            x_start=x,
            load_start=prev,
            pressure_start=p,
            solver=solver,
            options=SolverOptions(tolerance=1e-8),
        )
        if i < 13:
            first.append(res.x)
        else:
            assert res.iterations == 0
            assert np.array_equal(res.x, first[i - 13 + 1])
        x, p, prev = res.x, res.pressure_kpa, load


def test_cg_stops_at_its_displacement_goal_only_within_its_residual_bound():
    """CG on a 1-D chain of springs (stiffness 1, 100 dofs, load 1 at one end) with a
    Jacobi preconditioner: asked for rtol 1e-12, with the goal (1e-2, 1.0) it stops at the
    first iterate whose preconditioned residual is within 1e-2 and counts as converged;
    with the residual bound 1e-12 the goal never applies and it runs to rtol."""
    n = 100
    k = 2.0 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
    b = np.zeros(n)
    b[-1] = 1.0
    jacobi = 1.0 / np.diag(k)

    def precond(r):
        return jacobi * r

    full, its_full, ok_full = linsolve.pcg(k.__matmul__, precond, b, 1e-12, 400)
    early, its, ok = linsolve.pcg(k.__matmul__, precond, b, 1e-12, 400, None, (1e-2, 1.0))
    assert ok and ok_full and its < its_full
    assert np.abs(precond(b - k @ early)).max() <= 1e-2
    previous, _, _ = linsolve.pcg(k.__matmul__, precond, b, 1e-12, its - 1)
    assert np.abs(precond(b - k @ previous)).max() > 1e-2
    bounded, its_b, _ = linsolve.pcg(k.__matmul__, precond, b, 1e-12, 400, None, (1e-2, 1e-12))
    assert its_b == its_full
    assert np.allclose(bounded, full, rtol=0, atol=1e-9)
