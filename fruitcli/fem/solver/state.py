"""Quasi-static equilibrium of one state (`solve_state`): load steps from the start's
load to the state's, halved when Newton (`newton`) does not converge on one (with
`SolverOptions.path_tolerance`, those short of the state's load converged only to it,
and the state solved again from its start without it when a step fails). Each load
step starts from a secant predictor: along the load path from the two previous steps,
or, for a new state, from the previous states kept on the linear solver (`predictor`);
Newton retries from the plain start if it fails. A body stiff in bulk is solved from
rest through softer bulk moduli first (`continuum.FIRST_BULK_RATIO`). Also the lines
a failing or overrunning state reports.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from fruitcli.errors import SolverError
from fruitcli.fem.fem_model import BulkStaged, FemModel, LinearSolver
from fruitcli.fem.solver.newton import NewtonStep, iterate
from fruitcli.fem.solver.options import OutOfTime, SolverOptions, StateResult
from fruitcli.fem.solver.predictor import (
    history_guess,
    load_vector,
    remember,
    remember_sensitivity,
    sensitivity_guess,
)
from fruitcli.fem.solver.prescribed import impose_prescribed, lift_prescribed
from fruitcli.fem.state_load import Load
from fruitcli.fem.tolerances import FORCE_FLOOR, MIN_DET_F

DEFAULT_OPTIONS = SolverOptions()
"""The options of a state solved without any (the [solver] defaults)."""

PATH_TOLERANCE = 0.01
"""The `SolverOptions.path_tolerance` of a state solved from rest in several load steps
(`fruit simulate`'s first state): a step short of the state's load only brings the
next one's start within Newton's reach, and the last converges to the tolerance, so the
equilibrium is the same. On the default Fruit from rest (its weight and 9 kPa in two
chambers, 4 load steps) each step's first Newton step removes the bulk error of a start
extrapolated along straight lines and leaves a relative residual of about 1e-2: 9 Newton
steps, 4 factorizations and 92 CG iterations instead of 13, 5 and 146, the equilibrium
within 8e-6 mm of the state solved to 1e-11 (every step to the tolerance: 6e-5 mm).
0.1 saved one factorization more there, but on a beam turning far under its weight
(`tests/fem/solver/test_path_tolerance.py`) it took 85 Newton steps instead of 58,
where 0.01 takes 54 (both with the refactorization below).

Along such steps each step's second Newton step also factors its tangent afresh
(`NewtonStep.refactor_second`): the first removes the bulk error of the step's start
and leaves the kept factor too far from the tangent for CG (on the default Fruit, 24 CG
iterations in the last step and then a refactorization all the same). With it the
default Fruit's state took 8 Newton steps, 4 factorizations and 36 CG iterations
instead of 9, 4 and 92 (3.0 s instead of 4.1 s at load average 0.8-2)."""

PROGRESS_SECONDS = 2.0
"""A state running longer than this reports where it is (part of the load, Newton
iteration, relative residual) this often through `solve_state`'s `progress`."""


def solve_state(
    model: FemModel,
    load: Load,
    x_start: np.ndarray | None = None,
    load_start: Load | None = None,
    pressure_start: np.ndarray | None = None,
    options: SolverOptions = DEFAULT_OPTIONS,
    solver: LinearSolver | None = None,
    label: str = "state",
    progress: Callable[[str], None] | None = None,
) -> StateResult:
    """Equilibrium under `load`, continuing from `x_start` (default: rest) reached under
    `load_start` (default: zero load) with chamber pressures `pressure_start`. Pass the
    same `solver` across states to reuse its factorization. Raises SolverError naming
    `label`, the residual and the worst element when subdivision does not help, and
    OutOfTime past options.max_seconds. `progress(msg)`, when given, hears where a state
    running longer than PROGRESS_SECONDS is (load fraction, Newton step, residual).

    The load steps go from t = 0 (load_start) to 1 (load), options.load_steps of them
    at first; a step Newton does not converge on is retried once from the last
    equilibrium when its start was predicted, then halved (at most
    options.max_subdivisions times in all)."""
    t0 = time.perf_counter()
    k = len(model.chamber_tris)
    vc = np.asarray(load.volume_controlled, bool) if k else np.zeros(0, bool)
    if load_start is None:
        load_start = Load.zero(k, vc)
    if x_start is None and (load.is_zero() or _unloaded(model, load)):
        return _result(model, model.rest.copy(), np.zeros(k), 0, 0.0, 0, t0)
    stages = model.bulk_stages() if x_start is None else []
    if stages and isinstance(model, BulkStaged):
        return _through_bulk_stages(
            model, load, load_start, pressure_start, stages, options, solver, label, progress
        )
    x = model.rest.copy() if x_start is None else np.array(x_start, float)
    p = np.zeros(k) if pressure_start is None else np.array(pressure_start, float)
    if k:
        p[~vc] = load_start.pressure_kpa[~vc]
    solver = solver or model.make_solver(options.linear_solver)
    t, dt, det_ok = 0.0, 1.0 / max(1, options.load_steps), None
    path = _LoadPath(
        model,
        load,
        load_start,
        solver,
        options,
        label,
        progress,
        deadline=t0 + options.max_seconds if options.max_seconds > 0 else None,
        told=[t0],
        kept=_kept_start(solver, x_start, load) if dt == 1.0 else None,
    )
    iterations, subdivisions, merit, det_f = 0, 0, 0.0, np.ones(1)
    last = None  # (t, x, p) of the load step before the last one, for the predictor
    retry = False
    loose = options.path_tolerance > options.tolerance  # steps short of the load
    begin = (x, p, dt)
    while t < 1.0:
        t_new = min(1.0, t + dt)
        step_load = load_start.lerp(load, t_new)
        x_try, p_try = path.predict(t, t_new, step_load, x, p, last, retry)
        step = path.step(t, t_new, step_load, x, p)
        ok, x_new, p_new, its, merit, det_f = path.newton(
            step, x_try, p_try, t, p, loose and t_new < 1.0
        )
        iterations += its
        if ok:
            last = (t, x, p)
            x, p, t, det_ok, retry = x_new, p_new, t_new, det_f, False
            continue
        if x_try is not x and not retry:  # the predictor may have misled Newton: retry
            retry = True  # from x first
            continue
        retry = False
        if loose and t > 0.0:  # from a step converged to path_tolerance: start again
            loose, t, last, det_ok = False, 0.0, None, None
            x, p, dt = begin
            continue
        subdivisions += 1
        if subdivisions > options.max_subdivisions:
            raise path.no_equilibrium(subdivisions - 1, t, t_new, merit, det_f)
        dt *= 0.5
    first = not solver.history
    solver.history = remember(solver.history, load_vector(load), x, p)
    if first:
        remember_sensitivity(model, solver, x, load, iterations)
    return _result(model, x, p, iterations, merit, subdivisions, t0, det_ok)


def _kept_start(
    solver: LinearSolver, x_start: np.ndarray | None, load: Load
) -> tuple[tuple[np.ndarray, np.ndarray], bool] | None:
    """(x (n, 3) mm, p (K,) kPa) a state's last load step starts from, guessed from the
    states kept on the solver (`predictor.history_guess`, else
    `predictor.sensitivity_guess`), and whether `load` is a kept state's own; None
    without a guess."""
    repeated = any(np.array_equal(h[0], load_vector(load)) for h in solver.history)
    guess = history_guess(solver.history, x_start, load)
    if guess is None:
        guess = sensitivity_guess(solver, x_start, load)
    return None if guess is None else (guess, repeated)


@dataclass(frozen=True)
class _LoadPath:
    """What stays the same over the load steps of one state (`solve_state`): from
    `load_start` (t = 0) to `load` (t = 1) on `model`, with `solver`."""

    model: FemModel
    load: Load
    load_start: Load
    solver: LinearSolver
    options: SolverOptions
    label: str
    progress: Callable[[str], None] | None
    deadline: float | None  # time.perf_counter() past which the state stops (s)
    told: list[float]  # when `progress` last heard of the state (time.perf_counter(), s)
    kept: tuple[tuple[np.ndarray, np.ndarray], bool] | None  # `_kept_start`

    @property
    def vc(self) -> np.ndarray:
        """(K,) bool: the volume-controlled chambers (none without chambers)."""
        if not len(self.model.chamber_tris):
            return np.zeros(0, bool)
        return np.asarray(self.load.volume_controlled, bool)

    def predict(
        self,
        t: float,
        t_new: float,
        step_load: Load,
        x: np.ndarray,
        p: np.ndarray,
        last: tuple[float, np.ndarray, np.ndarray] | None,
        retry: bool,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Start (x (n, 3) mm, p (K,) kPa) of the load step from t to t_new (parts of
        the load) from the equilibrium (x, p) at t: the secant through `last` (the
        equilibrium before, at its t) and (x, p) along the load path; for a state's
        only step, the guess from the kept states; x itself when `retry`. The
        pressure-controlled chambers at the step's pressures, the moved regions where
        the step puts them (the free dofs following a move from x, `lift_prescribed`)."""
        model, vc = self.model, self.vc
        x_try, p_try = x, p.copy()
        rotating = self.load.jig != self.load_start.jig and any(j.rotate_deg for j in model.jigs)
        secant = model.secant_while_rotating or not rotating
        if last is not None and not retry and secant:  # secant predictor along the path
            s = (t_new - t) / (t - last[0])
            x_try, p_try = x + s * (x - last[1]), p + s * (p - last[2])
        elif self.kept is not None and t_new == 1.0 and not retry:  # over the states
            x_try, p_try = self.kept[0][0], self.kept[0][1].copy()
        if len(model.chamber_tris):
            p_try[~vc] = step_load.pressure_kpa[~vc]
        if x_try is x and len(model.prescribed_dofs) and not retry:
            at = self.load_start.lerp(self.load, t)
            x_try = lift_prescribed(model, self.solver, x, at, step_load)
        return impose_prescribed(model, x_try, step_load), p_try

    def step(
        self, t: float, t_new: float, step_load: Load, x: np.ndarray, p: np.ndarray
    ) -> NewtonStep:
        """Newton's load step from the equilibrium (x, p) at t to t_new, its force
        scale the external loads at both ends (`_reference_force`), with the state's
        deadline and progress."""
        model = self.model
        scale = FORCE_FLOOR * model.young_modulus_kpa * model.extent_mm**2
        at = self.load_start.lerp(self.load, t)
        step = NewtonStep(
            model, self.solver, step_load, _reference_force(model, x, p, at, step_load, scale)
        )
        step.deadline = self.deadline
        # along loose steps, each step's first Newton step leaves the kept factor stale
        # for its second (`PATH_TOLERANCE`)
        step.refactor_second = self.options.path_tolerance > self.options.tolerance
        # a kept state of this very load needs no Newton step: no tangent at its start
        step.tangent_at_start = not (t_new == 1.0 and self.kept is not None and self.kept[1])
        if self.progress is not None:
            step.report = functools.partial(
                _report, self.progress, self.told, self.label, t_new, self.options.tolerance
            )
        return step

    def newton(
        self,
        step: NewtonStep,
        x: np.ndarray,
        p: np.ndarray,
        t: float,
        p_at_t: np.ndarray,
        loose: bool = False,
    ) -> tuple[bool, np.ndarray, np.ndarray, int, float, np.ndarray]:
        """`newton.iterate` from (x, p) on `step` (to options.path_tolerance when
        `loose`); past the deadline, OutOfTime with the one line naming where the state
        stopped (t and the pressures p_at_t there)."""
        options = self.options
        if loose:
            options = replace(options, tolerance=options.path_tolerance)
        try:
            return iterate(step, x, p, options)
        except OutOfTime:
            line = _out_of_time(
                self.model,
                self.label,
                self.options.max_seconds,
                t,
                p_at_t,
                self.load,
                self.load_start,
            )
            raise OutOfTime(line, t) from None

    def no_equilibrium(
        self, halvings: int, t: float, t_new: float, merit: float, det_f: np.ndarray
    ) -> SolverError:
        """The one line of a state whose load step from t to t_new failed after
        `halvings` halvings: where it stopped, its relative residual `merit`, the worst
        element (det_f per element) and a hint at the likely cause."""
        vc = self.vc
        hint = "lower the load or raise [solver].max_subdivisions"
        if len(self.model.chamber_tris) and np.any(self.load.pressure_kpa[~vc]):
            hint = (
                "a chamber pressure may be past the body's limit point (the largest "
                "pressure it can hold while inflating): control its volume "
                "([actuation].volume_growth_mm3) to follow the inflation past it"
            )
        if det_f.min() <= 1.01 * MIN_DET_F:
            hint = (
                "elements are about to invert: the load is likely past what the body "
                "can carry (a chamber past its limit pressure: control its volume)"
            )
        return SolverError(
            f"{self.label}: no equilibrium after {halvings} load subdivisions "
            f"(reached {t:.3f} of the load step, relative residual {merit:.2e} at "
            f"{t_new:.3f}; worst element {self.model.worst_element(det_f)}); {hint}"
        )


def _through_bulk_stages(
    model: BulkStaged,
    load: Load,
    load_start: Load,
    pressure_start: np.ndarray | None,
    stages: list[float],
    options: SolverOptions,
    solver: LinearSolver | None,
    label: str,
    progress: Callable[[str], None] | None,
) -> StateResult:
    """`solve_state` from rest of a body stiff in bulk (`continuum.FIRST_BULK_RATIO`):
    with each bulk modulus of `stages` (kPa) in turn, the first from rest along
    options.load_steps and each next from the last equilibrium, on a solver of their own
    (`solver` keeps only states of the body itself), then with the body's own bulk
    modulus from the last. A stage after the first changes no load, so it is not
    subdivided: when one fails, the state is solved from rest as without stages. Past
    options.max_seconds, one OutOfTime line names the stage reached. Iterations and
    subdivisions count every stage that converged, the time all."""
    t0 = time.perf_counter()

    def budget(opts: SolverOptions) -> SolverOptions:  # the state's time budget left
        if options.max_seconds <= 0:
            return opts
        return replace(opts, max_seconds=max(options.max_seconds - time.perf_counter() + t0, 1e-3))

    after = replace(options, load_steps=1, max_subdivisions=0)
    staged = model.make_solver(options.linear_solver)
    x, p, start = model.rest.copy(), pressure_start, load_start
    iterations, subdivisions = 0, 0
    own = model.material.bulk_modulus_kpa
    try:
        for i, kappa in enumerate(stages):
            at = f"bulk modulus {kappa:.4g} kPa"
            with model.bulk_modulus(kappa):
                r = solve_state(
                    model,
                    load,
                    x,
                    start,
                    p,
                    budget(after if i else options),
                    staged,
                    f"{label} (bulk modulus {kappa:.4g} kPa)",
                    progress,
                )
            x, p, start = r.x, r.pressure_kpa, load
            iterations, subdivisions = iterations + r.iterations, subdivisions + r.subdivisions
        at = f"its own bulk modulus, {own:.4g} kPa"
        r = solve_state(model, load, x, load, p, budget(after), solver, label, progress)
    except OutOfTime as exc:
        raise _stage_out_of_time(label, options, at, exc) from None
    except SolverError:
        at = f"its own bulk modulus, {own:.4g} kPa, from rest (a softer stage failed)"
        try:
            r = solve_state(
                model,
                load,
                model.rest.copy(),
                load_start,
                pressure_start,
                budget(options),
                solver,
                label,
                progress,
            )
        except OutOfTime as exc:
            raise _stage_out_of_time(label, options, at, exc) from None
    return replace(
        r,
        iterations=iterations + r.iterations,
        subdivisions=subdivisions + r.subdivisions,
        solve_ms=1e3 * (time.perf_counter() - t0),
    )


def _stage_out_of_time(label: str, options: SolverOptions, at: str, exc: OutOfTime) -> OutOfTime:
    """The one line of a state through bulk stages stopped at its time budget: the
    configured budget and the stage it was in (`at`)."""
    return OutOfTime(
        f"{label}: stopped after {options.max_seconds:g} s ([solver].max_seconds) at "
        f"{at} (a body this stiff in bulk is solved through softer bulk moduli first); "
        "raise [solver].max_seconds",
        exc.fraction,
    )


def _report(
    progress: Callable[[str], None],
    told: list[float],
    label: str,
    fraction: float,
    tolerance: float,
    iteration: int,
    merit: float,
) -> None:
    """Tell `progress` where the state is, at most every PROGRESS_SECONDS: the part of
    the load its load step goes to, the Newton iteration, and the residual force
    relative to the step's load (converged at `tolerance`)."""
    now = time.perf_counter()
    if now - told[0] >= PROGRESS_SECONDS:
        told[0] = now
        progress(
            f"{label}: {fraction:.0%} of the load, Newton iteration {iteration}, "
            f"relative force residual {merit:.1e} (tolerance {tolerance:.0e})"
        )


def _out_of_time(
    model: FemModel,
    label: str,
    seconds: float,
    t: float,
    p: np.ndarray,
    load: Load,
    load_start: Load,
) -> str:
    """The one line of a state stopped at its time budget."""
    reached = load_start.lerp(load, t)
    vc = np.asarray(reached.volume_controlled, bool)
    where = ", ".join(
        f"{name} {reached.volume_growth_mm3[i]:.4g} mm^3 at {p[i]:.4g} kPa"
        if vc[i]
        else f"{name} {reached.pressure_kpa[i]:.4g} kPa"
        for i, name in enumerate(model.chamber_names)
    )
    return (
        f"{label}: stopped after {seconds:g} s ([solver].max_seconds) at {t:.3f} of the "
        f"load step"
        + (f" (chambers: {where})" if where else "")
        + "; a chamber may be past its limit pressure (`fruit limits` computes it), or "
        "raise [solver].max_seconds"
    )


def _unloaded(model: FemModel, load: Load) -> bool:
    """True when the load is zero in effect: no chamber load, gravity or jig scale
    multiplying zero, a jig whose target is its rest position, no moved region."""
    if np.any(load.pressure_kpa) or np.any(load.volume_growth_mm3):
        return False
    if load.prescribed and np.any(model.prescribed_mm):
        return False
    if load.gravity and np.any(model.body_force_mn):
        return False
    return not (load.jig and any(j.rotate_deg or np.any(j.translate_mm) for j in model.jigs))


def _result(
    model: FemModel,
    x: np.ndarray,
    p: np.ndarray,
    iterations: int,
    merit: float,
    subdivisions: int,
    t0: float,
    det_f: np.ndarray | None = None,
) -> StateResult:
    """The state at x (n, 3) mm with chamber pressures p (K,) kPa, reached in
    `iterations` Newton steps and `subdivisions` halvings since time.perf_counter() t0
    (s) at relative residual `merit`; det_f: det F per element at x, when known."""
    if det_f is None:
        det_f = model.min_det_f(x)
    volumes = model.chamber_volumes(x) if len(model.chamber_tris) else np.zeros(0)
    return StateResult(
        x=x,
        displacement_mm=x - model.rest,
        pressure_kpa=p,
        chamber_volume_mm3=volumes,
        iterations=iterations,
        residual=merit,
        subdivisions=subdivisions,
        min_det_f=float(det_f.min()),
        solve_ms=1e3 * (time.perf_counter() - t0),
    )


def _reference_force(
    model: FemModel, x: np.ndarray, p: np.ndarray, load_a: Load, load_b: Load, floor: float
) -> float:
    """Force scale of a load step: the largest of the external loads at both ends (the
    elastic force at the start joins it at the step's first evaluation) (mN)."""
    free = model.pattern.free
    h = model.chamber_gradients(x) if len(model.chamber_tris) else None
    fa = model.external_forces(x, p, load_a, h).reshape(-1)[free]
    pb = p.copy()
    if len(pb):
        pb[~load_b.volume_controlled] = load_b.pressure_kpa[~load_b.volume_controlled]
    fb = model.external_forces(x, pb, load_b, h).reshape(-1)[free]
    return max(float(np.linalg.norm(fa)), float(np.linalg.norm(fb)), floor)
