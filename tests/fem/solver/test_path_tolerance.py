"""A state solved from rest in several load steps with `SolverOptions.path_tolerance`
(`fruit simulate`'s first state): the steps short of the load converge only to it, the
last to the tolerance, and the equilibrium is the one every step converged to the
tolerance reaches; a step that fails after a loose one has the state solved again from
its start with every step to the tolerance."""

import numpy as np

from fruitcli.fem.solver import state
from fruitcli.fem.solver.options import SolverOptions
from fruitcli.fem.state_load import Load
from tests.fem.materials.test_hyperelastic import sagging_beam


def spied(monkeypatch, fail_tight: int = 0) -> list:
    """(tolerance, converged) of each Newton run from here on; the first `fail_tight`
    ones at the full tolerance after a loose one report no convergence."""
    calls: list = []
    real = state.iterate

    def iterate(step, x, p, options):
        loose_before = any(tol > 1e-6 for tol, _ in calls)
        failed = sum(not ok for _, ok in calls)
        if options.tolerance == 1e-6 and loose_before and failed < fail_tight:
            calls.append((options.tolerance, False))
            return False, x, p, 0, np.inf, np.ones(1)
        out = real(step, x, p, options)
        calls.append((options.tolerance, out[0]))
        return out

    monkeypatch.setattr(state, "iterate", iterate)
    return calls


def test_loose_steps_on_the_way_reach_the_same_equilibrium(monkeypatch):
    """The 60 mm beam sagging 51 mm under its weight (nu = 0.49), from rest in 4 load
    steps: with the path tolerance, the three steps short of the load converge to it and
    the last to 1e-6; both states lie within 1e-4 of the largest displacement (5 um) of
    the equilibrium solved to 1e-11, at a residual within the tolerance."""
    m = sagging_beam(0.49)
    load = Load.pressures([], gravity=1.0)
    calls = spied(monkeypatch)
    loose = state.solve_state(
        m, load, options=SolverOptions(load_steps=4, path_tolerance=state.PATH_TOLERANCE)
    )
    assert [tol for tol, ok in calls if ok] == [state.PATH_TOLERANCE] * 3 + [1e-6]
    calls.clear()
    tight = state.solve_state(m, load, options=SolverOptions(load_steps=4))
    assert {tol for tol, _ in calls} == {1e-6}
    exact = state.solve_state(
        m, load, tight.x, load, options=SolverOptions(tolerance=1e-11, linear_solver="direct")
    )
    sag = np.abs(exact.displacement_mm).max()
    assert sag > 50.0
    for res in (loose, tight):
        assert res.residual <= 1e-6
        assert np.abs(res.x - exact.x).max() <= 1e-4 * sag


def test_a_step_failing_after_a_loose_one_solves_the_state_again_from_its_start(monkeypatch):
    """The last step (after three loose ones) reports no convergence from its predicted
    start and from the last step's equilibrium: the state is solved again from rest in
    the same 4 steps, each to the tolerance (no halving), to the equilibrium of the state
    solved so in the first place."""
    m = sagging_beam(0.49)
    load = Load.pressures([], gravity=0.5)
    calls = spied(monkeypatch, fail_tight=2)
    res = state.solve_state(
        m, load, options=SolverOptions(load_steps=4, path_tolerance=state.PATH_TOLERANCE)
    )
    tols = [tol for tol, _ in calls]
    assert tols[:3] == [state.PATH_TOLERANCE] * 3 and calls[3:5] == [(1e-6, False)] * 2
    assert tols[5:] == [1e-6] * 4 and all(ok for _, ok in calls[5:])
    assert res.subdivisions == 0 and res.residual <= 1e-6
    tight = state.solve_state(m, load, options=SolverOptions(load_steps=4))
    assert np.abs(res.x - tight.x).max() <= 1e-4 * np.abs(tight.displacement_mm).max()
