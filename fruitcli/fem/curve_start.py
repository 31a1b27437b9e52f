"""How a body's pressure-volume curves start (`fruitcli.fem.limits`): the body's
equilibrium under its weight, shared by its curves (`start_state`), and each curve's
first sample from there or from rest (`first_sample`), screened at a loose tolerance
when its bound may refuse the pressure asked at once (`first_kept_or_solved`). Also
the loads of a curve (`chamber_load`, `ratio_of`). Units: mm, mm^3, kPa.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from fruitcli.errors import SolverError
from fruitcli.fem.curve_peak import refusing_bound
from fruitcli.fem.fem_model import FemModel, LinearSolver
from fruitcli.fem.linear_response import Start, response
from fruitcli.fem.sample_cache import SampleCache, kept_or_solved
from fruitcli.fem.solver.options import OutOfTime, SolverOptions, StateResult
from fruitcli.fem.solver.state import PATH_TOLERANCE, solve_state
from fruitcli.fem.state_load import Load

Chambers = int | np.integer | np.ndarray | Sequence[float]
"""A curve's chambers: one chamber's index, or pressure ratios (K,) of them together."""


FIRST_STEPS = 3
"""Load steps of the body's equilibrium under its weight from rest (`start_state`), and
of a first sample that finds none from the start's linear response: on the default
Fruit (gravity, fixed base) the weight alone took 14 Newton steps in one load step, 9 in
3 and 11 in 4; the weight and chamber c1's first volume step at once took 21 in one load
step, 10 (7-8 s) in 3, 11 in 4, 15 in 6 and 19 in 2, with the same pressure to 5
digits."""


SCREEN_TOLERANCE = 0.1
"""Newton's relative residual, in every load step, of the first sample of a curve the
pressure check follows with the slope at rest (`first_kept_or_solved`), whose bound may
then refuse the pressure asked at once: on the default Fruit chamber c1's under its
weight took 4 Newton steps instead of 7, its pressure within 0.11 % of the one at
`limits.CHECK_TOLERANCE` (-8.124 against -8.1245 kPa at 0.729 V0, 8.383 against 8.392
kPa at 1.331 V0), far inside the bound's `curve_peak.ONE_SAMPLE_MARGIN`. A sample the
bound does not refuse on, converged on from there, took the same 7 Newton steps in all
(4 and 3) and 2.8-3.1 s against 2.8 s."""


def chamber_load(model: FemModel, k: int, growth_mm3: float) -> Load:
    """Chamber k held at rest volume + growth_mm3, the other chambers at pressure 0;
    gravity and jigs as in the scene's states (full)."""
    n = len(model.chamber_tris)
    growth = np.zeros(n)
    growth[k] = growth_mm3
    vc = np.zeros(n, bool)
    vc[k] = True
    return Load(np.zeros(n), growth, vc, 1.0, 1.0)


def chamber_index(k: Chambers) -> int | None:
    """The chamber a curve follows alone (k an int), or None for pressure ratios."""
    return int(k) if isinstance(k, (int, np.integer)) else None


def ratio_of(model: FemModel, k: Chambers) -> np.ndarray:
    """(K,) pressure ratios of a curve: chamber k alone (an int), or the given ratios
    scaled to a largest of 1."""
    if isinstance(k, (int, np.integer)):
        return np.eye(len(model.chamber_tris))[k]
    r = np.asarray(k, float)
    return r / np.abs(r).max()


def forget(solver: LinearSolver) -> None:
    """Clear what the curve's states left on the solver for the next state's predictor
    (`newton._history_guess`, `_sensitivity_guess`), and have its next tangent factored
    afresh (the kept factor is of a deformed state); its analysis stays."""
    solver.history, solver.sensitivity, solver.estimated = [], None, None
    if hasattr(solver, "refresh"):
        solver.refresh = True


def start_state(
    model: FemModel,
    solver: LinearSolver,
    options: SolverOptions,
    progress: Callable[[str], None] | None = None,
) -> Start:
    """The `Start` of a body's curves, on `solver` (forgotten afterwards, `forget`): under
    a body force its equilibrium under the weight alone (pressure 0 in every chamber),
    solved from rest once for all the curves in FIRST_STEPS load steps (on the default
    Fruit the weight sags the body by 20 mm: 9 Newton steps), instead of each curve's
    first sample carrying the weight from rest (10 Newton steps each); rest otherwise."""
    x = model.rest.copy()
    k = len(model.chamber_tris)
    if np.any(getattr(model, "body_force_mn", 0.0)):
        res = solve_state(
            model,
            Load.pressures(np.zeros(k)),
            options=replace(
                options,
                load_steps=max(options.load_steps, FIRST_STEPS),
                path_tolerance=PATH_TOLERANCE,
            ),
            solver=solver,
            label="the body under its weight",
        )
        x = res.x
        if progress:
            progress(
                f"limits: the body under its weight ({res.iterations} Newton steps, "
                f"{res.solve_ms / 1e3:.1f} s)"
            )
    dx_dp, compliance = response(model, solver, x)
    forget(solver)
    return Start(x, model.chamber_volumes(x), dx_dp, compliance)


def first_sample(
    model: FemModel,
    k: Chambers,
    r: np.ndarray,
    start: Start | None,
    load: Load,
    growth: float,
    options: SolverOptions,
    solver: LinearSolver,
    name: str,
) -> StateResult:
    """The first sample of a curve (chamber k alone, or the chambers along ratios r) at
    volume growth `growth` over the rest volume, from the `Start` and its linear response
    (the pressure that makes the volume, and the nodes moved by it) in one load step;
    from the start itself in FIRST_STEPS load steps when that finds no equilibrium.
    Without a start (None), from rest, in FIRST_STEPS load steps under a body force, those
    short of its load to `state.PATH_TOLERANCE` (on the default Fruit 7 Newton steps
    instead of 10 at the check's tolerance in every step)."""
    if start is None:
        if np.any(getattr(model, "body_force_mn", 0.0)):
            options = replace(
                options,
                load_steps=max(options.load_steps, FIRST_STEPS),
                path_tolerance=PATH_TOLERANCE,
            )
        return solve_state(model, load, options=options, solver=solver, label=f"chamber {name}")
    alone = chamber_index(k)
    grown = start.volume_mm3 - model.chamber_rest_volume_mm3
    if alone is not None:
        before = chamber_load(model, alone, float(grown[alone]))
        dp = np.zeros(len(r))
        dp[alone] = (growth - grown[alone]) / start.compliance[alone, alone]
    else:
        before = Load.together(r, float(r @ grown))
        dp = r * (growth - float(r @ grown)) / float(r @ start.compliance @ r)
    try:
        return solve_state(
            model,
            load,
            x_start=start.x + start.dx_dp @ dp,
            pressure_start=dp,
            options=options,
            load_start=before,
            solver=solver,
            label=f"chamber {name}",
        )
    except OutOfTime:
        raise
    except SolverError:
        forget(solver)
        steps = replace(options, load_steps=max(options.load_steps, FIRST_STEPS))
        return solve_state(
            model,
            load,
            x_start=start.x,
            pressure_start=np.zeros(len(r)),
            options=steps,
            load_start=before,
            solver=solver,
            label=f"chamber {name}",
        )


def first_kept_or_solved(
    model: FemModel,
    samples: SampleCache | None,
    load: Load,
    solver: LinearSolver,
    name: str,
    first: Callable[[SolverOptions], StateResult],
    options: SolverOptions,
    screen: Callable[[StateResult], bool] | None,
) -> StateResult:
    """A curve's first sample (`first(options)`: `first_sample` but for its options),
    kept in or taken from `samples`. With a `screen` (whether the sample refuses the
    pressure asked at once, `refuses_at_once`) and none kept at the cache's tolerance:
    solved (or kept) to SCREEN_TOLERANCE first, and unless the screen refuses, converged
    on from there to the options' tolerance (solved afresh when that finds no
    equilibrium; each solve has the options' time budget), its Newton steps and time
    then those of both."""
    if screen is None:
        return kept_or_solved(samples, load, solver, lambda: first(options))
    kept = samples.get(load, solver) if samples is not None else None
    if kept is not None:
        return kept
    loose = replace(options, tolerance=max(options.tolerance, SCREEN_TOLERANCE))
    res = kept_or_solved(samples, load, solver, lambda: first(loose), loose.tolerance)
    if screen(res):
        return res
    done = res
    if res.residual > options.tolerance:
        label = f"chamber {name}"
        try:
            on = solve_state(model, load, res.x, load, res.pressure_kpa, options, solver, label)
        except OutOfTime:
            raise
        except SolverError:  # none from the loose sample: the sample afresh, as unscreened
            forget(solver)
            on = first(options)
        its, ms = res.iterations + on.iterations, res.solve_ms + on.solve_ms
        done = replace(on, iterations=its, solve_ms=ms)
    if samples is not None:
        samples.put(load, done)
    return done


def refuses_at_once(
    model: FemModel,
    r: np.ndarray,
    s: float,
    asked: float,
    end: float,
    slope: float,
    res: StateResult,
) -> bool:
    """Whether a curve's first sample `res` at mean stretch `s` (chambers along ratios
    r) refuses the pressure `asked` (kPa) by its bound towards the mean stretch `end`
    after one sample, with the slope at rest `slope` (`curve_peak.refusing_bound`)."""
    pressure = np.array([0.0, pressure_along(res, r)])
    return refusing_bound(model, pressure, np.array([1.0, s]), asked, end, slope) is not None


def pressure_along(res: StateResult, r: np.ndarray) -> float:
    """A sample's pressure (kPa) on its curve along the chambers' ratios r: the
    chamber's own for a chamber alone (what the curve records and its bound reads)."""
    return float(res.pressure_kpa @ r / (r @ r))
