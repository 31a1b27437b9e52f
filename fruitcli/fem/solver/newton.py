"""Quasi-static equilibrium of one state (the paper's eqs. 2-3): Newton iterations on
the consistent corotational tangent (with the follower-pressure stiffness; the projected
or SOFA's warped tangent when a step fails, see TANGENTS) with chamber pressures as
Lagrange multipliers, a backtracking line search, and load-step halving when a step does
not converge. Each load step starts from a secant predictor: along the load path from
the two previous steps, or, for a new state, from the previous states kept on the
TangentSolver (`_history_guess`); Newton retries from the plain start if it fails.

Residual r = f_ext(x, p) - f_int(x) over the free dofs; a volume-controlled chamber
adds the constraint V(x) = V_rest + growth with its pressure p as unknown. The linear
system [K  -H^T; H  0] is solved by the Schur complement W = H K^-1 H^T (mm^3/kPa).
"""

from __future__ import annotations

import functools
import itertools
import time
from dataclasses import dataclass, replace

import numpy as np

from fruitcli.errors import SolverError
from fruitcli.fem.corotational_model import Load
from fruitcli.fem.fem_model import FemModel
from fruitcli.fem.solver.linsolve import TangentSolver
from fruitcli.fem.tolerances import (
    ARMIJO,
    CHORD_CONTRACTION,
    ESTIMATE_SAFETY,
    ESTIMATE_WINDOW,
    FORCE_FLOOR,
    LINE_SEARCH_STEPS,
    LINEAR_DISPLACEMENT_SHARE,
    LINEAR_MARGIN,
    MIN_DET_F,
    PCG_RELATIVE_TOLERANCE,
    PCG_TARGET,
    STALL_RESIDUAL_FACTOR,
    STEP_TOLERANCE,
)


@dataclass(frozen=True)
class SolverOptions:
    """`tolerance`: |r| <= tolerance * reference force; `max_iterations` per load step;
    `max_subdivisions`: halvings of a failing step; `load_steps`: initial steps.

    `max_seconds` (0: none): the time budget of one state (s); past it the state
    fails with `OutOfTime`.

    `displacement_tolerance_mm` (0: off): Newton also stops once the solver's kept
    factor estimates that the remaining correction moves no node by more than this
    (mm; pressure-controlled loads only, see `_close_enough`).

    A state also counts as converged when round-off keeps the residual from reaching
    the tolerance: the residual is within STALL_RESIDUAL_FACTOR of it and the full
    Newton correction moves no node by more than STEP_TOLERANCE times the body size
    (see `fruitcli.fem.tolerances`)."""

    tolerance: float = 1e-6
    max_iterations: int = 25
    max_subdivisions: int = 6
    linear_solver: str = "pcg"
    load_steps: int = 1
    displacement_tolerance_mm: float = 0.0
    max_seconds: float = 0.0

    def __post_init__(self) -> None:
        """Refuse, with one line naming the [solver] key, an option that would make a
        state diverge, stop before solving or never end (SolverError)."""
        checks = (
            ("tolerance", 0.0 < self.tolerance < 1.0, "0 < tolerance < 1"),
            ("max_iterations", self.max_iterations >= 1, ">= 1"),
            ("max_subdivisions", self.max_subdivisions >= 0, ">= 0"),
            ("load_steps", self.load_steps >= 1, ">= 1"),
            ("displacement_tolerance_mm", self.displacement_tolerance_mm >= 0.0, ">= 0"),
            ("max_seconds", self.max_seconds >= 0.0, "a time budget > 0 s (0: none)"),
        )
        for key, ok, expected in checks:
            value = getattr(self, key)
            if not (ok and np.isfinite(value)):
                raise SolverError(f"[solver].{key}: expected {expected}, got {value!r}")


class OutOfTime(SolverError):
    """A state stopped at its time budget (`SolverOptions.max_seconds`); `fraction` is
    the part of the load step it had reached."""

    def __init__(self, message: str, fraction: float):
        super().__init__(message)
        self.fraction = fraction


PROGRESS_SECONDS = 2.0
"""A state running longer than this reports where it is (part of the load, Newton
iteration, relative residual) this often through `solve_state`'s `progress`."""


@dataclass
class StateResult:
    x: np.ndarray  # (n, 3) mm
    displacement_mm: np.ndarray  # (n, 3)
    pressure_kpa: np.ndarray  # (K,)
    chamber_volume_mm3: np.ndarray  # (K,)
    iterations: int
    residual: float  # relative, at convergence
    subdivisions: int
    min_det_f: float
    solve_ms: float


class _Step:
    """Newton on one load step; holds the work arrays of the current iterate."""

    def __init__(self, model: FemModel, solver: TangentSolver, load: Load, ref: float):
        self.m, self.solver, self.load, self.ref = model, solver, load, ref
        self.vc = np.flatnonzero(load.volume_controlled)
        # the controlled volumes c V (one row per constraint; p moves along c^T):
        # each volume-controlled chamber, or the chambers together (`Load.together`)
        k = len(load.volume_controlled)
        self.c = np.eye(k)[self.vc] if load.ratio is None else load.ratio[None, :]
        self.v_target = self.c @ (model.chamber_rest_volume_mm3 + load.volume_growth_mm3)
        self.v_ref = np.maximum(np.abs(self.c) @ model.chamber_rest_volume_mm3, 1.0)
        self.f_int_norm = 0.0
        self.deadline = None  # time.perf_counter() past which Newton stops (OutOfTime)
        # whether the start's evaluation brings the tangent along (`evaluate`)
        self.tangent_at_start = True
        self.report = None  # report(iteration, merit) when progress is asked for

    def evaluate(self, x, p, tangent: bool = False):
        """(rot, det_f, h, r, g, merit, energy, f) at x with chamber pressures p; with
        `tangent`, the model evaluates the element tangents in the same pass (a load
        step's start, whose tangent Newton's first step needs: on the quadratic default
        Fruit one element loop of 60-100 ms instead of that and a forces loop of 9-14
        ms; trial iterates do not, as a tangent evaluated for an iterate that then
        converges costs far more than the forces loop it would save)."""
        m = self.m
        f, rot, det_f = m.kinematics(x, tangent)
        h = m.chamber_gradients(x) if m.chamber_tris else None
        f_int, energy = m.forces_and_energy(f, rot)
        r = m.external_forces(x, p, self.load, h) - f_int
        r = r.reshape(-1)[m.pattern.free]
        energy += m.external_potential(x, p, self.load)
        g = self.c @ m.chamber_volumes(x) - self.v_target if len(self.vc) else np.zeros(0)
        # scale: the step's load, or the elastic force once it is larger (volume
        # control starts with an unknown pressure and no external load)
        self.f_int_norm = float(np.linalg.norm(f_int.reshape(-1)[m.pattern.free]))
        scale = max(self.ref, self.f_int_norm)
        merit = np.linalg.norm(r) / scale
        if len(g):
            merit = max(merit, float(np.max(np.abs(g) / self.v_ref)))
        return rot, det_f, h, r, g, merit, energy, f

    def direction(self, x, p, rot, h, r, g, f, level, keep_tangent=False):
        """Newton direction with the tangent of `level` (see TANGENTS), or with the
        solver's current tangent when `keep_tangent` (a chord step)."""
        m = self.m
        if keep_tangent:
            pass  # chord step: the solver keeps the tangent of the previous step
        elif TANGENTS[level] == "warped":
            self.solver.update(rot)
        else:
            exact = TANGENTS[level] == "exact"
            # assembled (about 1.5 ms here): a CSR product then costs next to nothing
            load_k = m.load_stiffness(x, p) if exact else None
            self.solver.update(rot, f, load_k, not exact)
        if not len(self.vc):
            return self.solver.solve(r), np.zeros(len(p))
        hv = (self.c @ h.reshape(len(self.c[0]), -1))[:, m.pattern.free]  # (kv, n_free)
        sol = self.solver.solve(np.column_stack([r, hv.T]))
        kr, kh = sol[:, 0], sol[:, 1:]
        w = hv @ kh  # compliance dV/dp (mm^3/kPa)
        dp = np.linalg.solve(w, -g - hv @ kr)
        return kr + kh @ dp, self.c.T @ dp


TANGENTS = ("exact", "projected", "warped")
"""Tangents tried in turn when a Newton step fails: the consistent one (rotation term and
follower-pressure stiffness; quadratic convergence near equilibrium), then without the
follower-pressure stiffness and with each element's rotation term clamped to positive
semi-definite (Teran 2005; positive definite, so a descent direction), then SOFA's
warped R K0 R^T (robust far from equilibrium, linear convergence). The consistent one
is skipped while an element is inverted or flat."""


def _newton(step: _Step, x, p, options: SolverOptions):
    """Returns (converged, x, p, iterations, merit, det_f)."""
    m = step.m
    rot, det_f, h, r, g, merit, energy, f = step.evaluate(x, p, step.tangent_at_start)
    if not np.isfinite(energy):  # an element inverted at the start (hyperelastic model)
        return False, x, p, 0, np.inf, det_f
    step.ref = max(step.ref, step.f_int_norm)  # the elastic force at the start counts
    size = m.extent_mm
    level = 0  # index into TANGENTS; raised for one step when a step fails
    chord, last_merit = False, np.inf  # whether the last step kept the tangent; its merit
    for it in range(options.max_iterations + 1):
        if merit <= options.tolerance or _close_enough(step, r, merit, options):
            return True, x, p, it, merit, det_f
        if it == options.max_iterations:
            break
        # not a step whose tangent's factorization (as long as the solver's last) would
        # end past the deadline
        _check_time(step, getattr(step.solver, "factor_seconds", 0.0))
        if step.report is not None:
            step.report(it, merit)
        if level == 0 and det_f.min() <= MIN_DET_F:
            level = 2
        # inexact Newton (Eisenstat-Walker): solve no more exactly than the nonlinear
        # residual this step will leave, C merit^2 (C observed on earlier full steps)
        # (first iteration of a step only: later ones converge less regularly)
        goal = PCG_TARGET * options.tolerance
        if it == 0:
            goal = max(goal, LINEAR_MARGIN * step.solver.newton_c * merit**2)
        # near the tolerance (within the solver's `near_tolerance` factor, 0 = never) the
        # last step only has to cross it: the linear solve may be as loose as the goal
        # asks, and the tangent of the previous step is kept (chord step); only right
        # after a step in Newton's quadratic regime (CHORD_CONTRACTION) and never twice
        # in a row (see CHORD_CONTRACTION)
        near = (
            it > 0
            and level == 0
            and not chord
            and merit <= CHORD_CONTRACTION * last_merit
            and merit <= getattr(step.solver, "near_tolerance", 0.0) * options.tolerance
        )
        chord, last_merit = near, merit
        cap = PCG_TARGET if near else PCG_RELATIVE_TOLERANCE
        step.solver.rtol = min(cap, max(goal / max(merit, 1e-300), 1e-12))
        # with a displacement tolerance, CG also stops once the factor estimates its
        # error within a share of what `_close_enough` accepts, with a residual within
        # that share of the window where it is asked (pressure control only)
        if options.displacement_tolerance_mm > 0.0 and not len(step.vc):
            share = LINEAR_DISPLACEMENT_SHARE
            step.solver.displacement_goal = (
                share * options.displacement_tolerance_mm / ESTIMATE_SAFETY,
                share * ESTIMATE_WINDOW * options.tolerance / max(merit, 1e-300),
            )
        try:
            dx_free, dp = step.direction(x, p, rot, h, r, g, f, level, keep_tangent=near)
        except SolverError:
            if level < 2:  # no factor of this tangent (singular): the next, safer one
                level += 1
                continue
            raise
        finally:
            step.solver.displacement_goal = (0.0, 1.0)  # Newton's steps only
        if (
            merit <= STALL_RESIDUAL_FACTOR * options.tolerance
            and np.abs(dx_free).max(initial=0.0) <= STEP_TOLERANCE * size
        ):
            return True, x, p, it, merit, det_f  # round-off stall: the correction is nil
        if not len(step.vc) and level < 2 and not float(r @ dx_free) > 0.0:
            level += 1  # not a descent direction: indefinite tangent
            continue
        dx = np.zeros(3 * m.n_nodes)
        dx[m.pattern.free] = dx_free
        dx = dx.reshape(-1, 3)
        alpha, accepted, trial = 1.0, False, None
        j_limit = m.dilatation_step
        j_now = np.abs(m.mean_dilatation(x) - 1.0) if j_limit else None
        for _ in range(LINE_SEARCH_STEPS):
            xt, pt = x + alpha * dx, p.copy()
            pt += alpha * dp
            if j_limit and np.any(np.abs(m.mean_dilatation(xt) - 1.0) > j_now + j_limit):
                alpha *= 0.5  # a spurious dilatation (see continuum.DILATATION_STEP)
                continue
            _check_time(step)
            trial = step.evaluate(xt, pt)
            if not (np.isfinite(trial[5]) and trial[1].min() > MIN_DET_F):
                alpha *= 0.5
                continue
            descent = len(step.vc) == 0 and (
                trial[6] <= energy - ARMIJO * alpha * float(r @ dx_free)
            )
            # volume control: a step's first full Newton step meets the volume but (a
            # nearly incompressible body's bulk term weighing its second-order part)
            # leaves a force residual above the volume error it started from; take it
            descent = descent or (
                len(step.vc) > 0
                and it == 0
                and alpha == 1.0
                and np.abs(trial[4]).max() < np.abs(g).max()
            )
            if descent or trial[5] < merit:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            if level < 2:
                level += 1
                continue
            return False, x, p, it + 1, merit, det_f if trial is None else trial[1]
        # a damped step says the tangent models the energy poorly here: take the next,
        # safer tangent until a full step is accepted again
        damped_escalates = m.escalate_on_damping
        level = 0 if alpha == 1.0 or not damped_escalates else min(level + 1, 2)
        x, p = xt, pt
        if it == 0 and alpha == 1.0 and merit > 0 and trial[5] > 3.0 * step.solver.rtol * merit:
            step.solver.newton_c = trial[5] / merit**2  # nonlinear part dominates: observe C
        rot, det_f, h, r, g, merit, energy, f = trial
    return False, x, p, options.max_iterations, merit, det_f


def _check_time(step: _Step, ahead: float = 0.0) -> None:
    """Raise OutOfTime when the step's deadline is less than `ahead` seconds away:
    checked before each Newton step's tangent (`ahead` one factorization) and each
    line-search evaluation (0), so that a state overruns its budget by little more than
    a factorization that takes longer than the last one."""
    if step.deadline is not None and time.perf_counter() + ahead > step.deadline:
        raise OutOfTime("time budget", 0.0)


def _close_enough(step: _Step, r: np.ndarray, merit: float, options: SolverOptions) -> bool:
    """True when the solver's kept factor K_0 estimates the Newton correction left at this
    iterate, K_0^-1 r, to move no node by more than options.displacement_tolerance_mm
    (with the margin ESTIMATE_SAFETY: K_0 is a stale, single-precision factor).
    Only for loads without volume-controlled chambers (their volume error would need a
    bound of its own) and once the residual is within ESTIMATE_WINDOW of the tolerance
    (each estimate costs one solve with the factor)."""
    dtol = options.displacement_tolerance_mm
    if not (dtol > 0.0 and not len(step.vc) and merit <= ESTIMATE_WINDOW * options.tolerance):
        return False
    z = step.solver.estimate(r)
    return z is not None and ESTIMATE_SAFETY * float(np.abs(z).max(initial=0.0)) <= dtol


def solve_state(
    model: FemModel,
    load: Load,
    x_start: np.ndarray | None = None,
    load_start: Load | None = None,
    pressure_start: np.ndarray | None = None,
    options: SolverOptions = SolverOptions(),
    solver: TangentSolver | None = None,
    label: str = "state",
    progress=None,
) -> StateResult:
    """Equilibrium under `load`, continuing from `x_start` (default: rest) reached under
    `load_start` (default: zero load) with chamber pressures `pressure_start`. Pass the
    same `solver` across states to reuse its factorization. Raises SolverError naming
    `label`, the residual and the worst element when subdivision does not help, and
    OutOfTime past options.max_seconds. `progress(msg)`, when given, hears where a state
    running longer than PROGRESS_SECONDS is (load fraction, Newton step, residual)."""
    t0 = time.perf_counter()
    deadline = t0 + options.max_seconds if options.max_seconds > 0 else None
    told = [t0]
    k = len(model.chamber_tris)
    vc = np.asarray(load.volume_controlled, bool) if k else np.zeros(0, bool)
    if load_start is None:
        load_start = Load.zero(k, vc)
    if x_start is None and (load.is_zero() or _unloaded(model, load)):
        return _result(model, model.rest.copy(), np.zeros(k), 0, 0.0, 0, t0)
    stages = model.bulk_stages() if x_start is None else []
    if stages:
        return _through_bulk_stages(
            model, load, load_start, pressure_start, stages, options, solver, label, progress
        )
    x = model.rest.copy() if x_start is None else np.array(x_start, float)
    p = np.zeros(k) if pressure_start is None else np.array(pressure_start, float)
    if k:
        p[~vc] = load_start.pressure_kpa[~vc]
    solver = solver or model.make_solver(options.linear_solver)
    scale = FORCE_FLOOR * model.young_modulus_kpa * model.extent_mm**2
    t, dt, det_ok = 0.0, 1.0 / max(1, options.load_steps), None
    iterations, subdivisions, merit, det_f = 0, 0, 0.0, np.ones(1)
    last = None  # (t, x, p) of the load step before the last one, for the predictor
    retry = False
    guess = None
    repeated = any(np.array_equal(h[0], _load_vector(load)) for h in solver.history)
    if dt == 1.0:
        guess = _history_guess(solver.history, x_start, load)
        if guess is None:
            guess = _sensitivity_guess(solver, x_start, load)
    rotating = load.jig != load_start.jig and any(j.rotate_deg for j in model.jigs)
    secant = model.secant_while_rotating or not rotating
    while t < 1.0:
        t_new = min(1.0, t + dt)
        step_load = load_start.lerp(load, t_new)
        x_try, p_try = x, p.copy()
        if last is not None and not retry and secant:  # secant predictor along the path
            s = (t_new - t) / (t - last[0])
            x_try, p_try = x + s * (x - last[1]), p + s * (p - last[2])
        elif guess is not None and t_new == 1.0 and not retry:  # secant over the states
            x_try, p_try = guess[0], guess[1].copy()
        if k:
            p_try[~vc] = step_load.pressure_kpa[~vc]
        if x_try is x and len(model.prescribed_dofs) and not retry:
            x_try = _lift_prescribed(model, solver, x, load_start.lerp(load, t), step_load)
        x_try = impose_prescribed(model, x_try, step_load)
        lifted = x_try is not x
        ref = _reference_force(model, x, p, load_start.lerp(load, t), step_load, scale)
        step = _Step(model, solver, step_load, ref)
        step.deadline = deadline
        # a kept state of this very load needs no Newton step: no tangent at its start
        step.tangent_at_start = not (t_new == 1.0 and guess is not None and repeated)
        if progress is not None:
            step.report = functools.partial(
                _report, progress, told, label, t_new, options.tolerance
            )
        try:
            ok, x_new, p_new, its, merit, det_f = _newton(step, x_try, p_try, options)
        except OutOfTime:
            raise OutOfTime(
                _out_of_time(model, label, options.max_seconds, t, p, load, load_start), t
            ) from None
        iterations += its
        if ok:
            last = (t, x, p)
            x, p, t, det_ok, retry = x_new, p_new, t_new, det_f, False
            continue
        if lifted and not retry:  # the predictor may have misled Newton: retry from x first
            retry = True
            continue
        retry = False
        subdivisions += 1
        if subdivisions > options.max_subdivisions:
            hint = "lower the load or raise [solver].max_subdivisions"
            if k and np.any(load.pressure_kpa[~vc]):
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
            raise SolverError(
                f"{label}: no equilibrium after {subdivisions - 1} load subdivisions "
                f"(reached {t:.3f} of the load step, relative residual {merit:.2e} at "
                f"{t_new:.3f}; worst element {model.worst_element(det_f)}); {hint}"
            )
        dt *= 0.5
    first = not solver.history
    solver.history = _remember(solver.history, _load_vector(load), x, p)
    if first:
        _remember_sensitivity(model, solver, x, load, iterations)
    return _result(model, x, p, iterations, merit, subdivisions, t0, det_ok)


def _through_bulk_stages(
    model, load, load_start, pressure_start, stages, options, solver, label, progress
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


def _stage_out_of_time(label: str, options, at: str, exc: OutOfTime) -> OutOfTime:
    """The one line of a state through bulk stages stopped at its time budget: the
    configured budget and the stage it was in (`at`)."""
    return OutOfTime(
        f"{label}: stopped after {options.max_seconds:g} s ([solver].max_seconds) at "
        f"{at} (a body this stiff in bulk is solved through softer bulk moduli first); "
        "raise [solver].max_seconds",
        exc.fraction,
    )


def _report(
    progress,
    told: list,
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
    model, label: str, seconds: float, t: float, p: np.ndarray, load: Load, load_start: Load
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


HISTORY_STATES = 16
"""Converged states kept (on the TangentSolver) for the predictor of the next: with 10,
a load path in a plane (e.g. phase-shifted sinusoids) is predicted to third order and
beyond (the weights' moments up to PREDICTOR_ORDER); 16 hold a whole cycle of the
breathing's 13 states, so that a repeated load finds its own earlier state (cycles
2-3: no Newton step, 1.7-2.2 ms per state instead of 7.7 ms with 10) and the first
cycle's later states have more to fit (1.33 Newton steps and 5.3 CG iterations per
state instead of 1.42 and 5.5 on p1, 2.00 and 13.7 instead of 2.08 and 14.4 on p2)."""

PREDICTOR_ORDER = 4
"""Highest order of the load moments sum_j c_j dq_j^(x k) the predictor's weights match
(each order within the weights left free by the lower ones, see `_moment_weights`)."""

PREDICTOR_MAX_WEIGHT = 4.0
"""Largest sum |c_j| of the affine (first-order) secant weights over the kept states."""

QUADRATIC_MAX_WEIGHT = 20.0
"""Largest sum |c_j| of the weights of second and higher order (they extrapolate
further, so they are larger: 6-17 on the default fruit's breathing); beyond it the
weights of the highest order within it."""

PREDICTOR_RCOND = 1e-8
"""Singular values of a moment system below this fraction of its largest count as zero:
those combinations of the weights are left to the next order."""


def _remember(history: list, q: np.ndarray, x: np.ndarray, p: np.ndarray) -> list:
    """The kept states with (q, x, p) appended, an earlier state of the same load q
    dropped (a repeated load, e.g. an animation closing its cycle, would otherwise take
    two of the HISTORY_STATES slots and leave too few distinct loads for the
    second-order guess), and the oldest dropped beyond HISTORY_STATES."""
    kept = [h for h in history if not np.array_equal(h[0], q)]
    return (kept + [(q, x, p)])[-HISTORY_STATES:]


def _load_vector(load: Load) -> np.ndarray:
    """The load as one vector: pressures (or volume growths where volume controlled),
    gravity, jig scale, and which chambers are volume controlled (1.0 or 0.0: a change
    of control mode makes the secant meaningless, see `_history_guess`)."""
    vc = np.asarray(load.volume_controlled, bool)
    return np.concatenate(
        [
            np.where(vc, load.volume_growth_mm3, load.pressure_kpa),
            [load.gravity, load.jig, load.prescribed],
            vc.astype(float),
        ]
    )


def _history_guess(history, x_start, load: Load):
    """Start of the next state from the previous converged ones: with q the load vector,
    dq = q_new - q_last and dq_j = q_j - q_last over the kept states j, weights c with
    sum_j c_j dq_j = dq give x = x_last + sum_j c_j (x_j - x_last) (likewise the
    pressures), exact for a response linear in the load. The weights left free also
    match sum_j c_j dq_j^(x k) = dq^(x k) for k = 2 .. PREDICTOR_ORDER as far as the kept
    states allow (`_moment_weights`), which makes the guess exact for a response
    polynomial of that order (on the default fruit's breathing one Newton step then
    mostly suffices). A load equal to a kept state's starts at that state (an
    equilibrium of the same load: an animation's next cycle). Used only when x_start is
    the last state kept, for loads changing like before (bounded weights); None
    otherwise."""
    if len(history) < 2 or x_start is None or not np.array_equal(x_start, history[-1][1]):
        return None
    q_last, x_last, p_last = history[-1]
    q = _load_vector(load)
    for q_j, x_j, p_j in history[:-1]:
        if np.array_equal(q_j, q):
            return x_j.copy(), p_j.copy()
    dq = q - q_last
    k = len(load.volume_controlled)
    if len(dq) != len(q_last) or not np.any(dq) or (k and np.any(dq[-k:])):
        return None
    prev = history[-2::-1]
    d = np.column_stack([h[0] - q_last for h in prev])
    c = _moment_weights(d, dq)
    if c is None:
        return None
    return _secant(prev, c, x_last, p_last)


def _secant(prev, c, x_last, p_last):
    """(x_last + sum_j c_j (x_j - x_last), the same of the pressures) over the kept states
    prev (load vector, x, p) with weights c."""
    x = x_last + sum(cj * (h[1] - x_last) for cj, h in zip(c, prev, strict=True))
    p = p_last + sum(cj * (h[2] - p_last) for cj, h in zip(c, prev, strict=True))
    return x, p


SENSITIVITY_RTOL = 1e-2
"""Relative residual of the solves K dx/dp_k = dH_k^T of `_remember_sensitivity`: they
only start Newton, which the tangent's own staleness already limits to first order."""


def _remember_sensitivity(model, solver, x: np.ndarray, load: Load, iterations: int) -> None:
    """Keep on the solver, at the first converged state x, (dx/dp (n, 3, K), C (K, K)):
    the nodes' response to each chamber's pressure, K^-1 H_k^T with the solver's current
    tangent (one CG solve per chamber, counted in this state's time and the solver's
    stats), and the chambers' volume compliance C = H dx/dp (mm^3/kPa).
    `_sensitivity_guess` starts the next states with it while the history is too short
    to span the load changes (a new animation's first states took 2-3 Newton steps
    instead of 1; the default Fruit's second sample of a pressure-volume curve 10 instead
    of 3). Nothing is kept without chambers, or when the state needed no Newton step
    (the solver has no tangent yet)."""
    solver.sensitivity = None
    k = len(model.chamber_tris)
    if iterations == 0 or k == 0:
        return
    free = model.pattern.free
    h = model.chamber_gradients(x).reshape(k, -1)[:, free]
    rtol = solver.rtol
    solver.rtol = SENSITIVITY_RTOL
    try:
        cols = solver.solve(np.ascontiguousarray(h.T)).reshape(len(free), k)
    except SolverError:
        return
    finally:
        solver.rtol = rtol
    sens = np.zeros((3 * model.n_nodes, k))
    sens[free] = cols
    solver.sensitivity = (sens.reshape(model.n_nodes, 3, k), h @ cols)


def _sensitivity_guess(solver, x_start, load: Load):
    """Start of the next state when `_history_guess` has none: the kept states' secant as
    far as they span the load change (least squares, bounded weights), the rest through
    the first state's dx/dp (`_remember_sensitivity`): a pressure-controlled chamber's
    pressure change directly, a volume-controlled one's volume change through the
    pressure change dp_v = C_vv^-1 (dV_v - C_vp dp_p) that makes it (chambers together
    along ratios r: dp = r (r.dV) / (r C r)). Only when x_start is the last state kept
    and nothing but the chambers' pressures or volumes changed; None otherwise."""
    kept = getattr(solver, "sensitivity", None)
    history = solver.history
    if (
        kept is None
        or not history
        or x_start is None
        or not np.array_equal(x_start, history[-1][1])
    ):
        return None
    sens, compliance = kept
    q_last, x_last, p_last = history[-1]
    dq = _load_vector(load) - q_last
    k = len(load.volume_controlled)
    if len(dq) != len(q_last) or k != sens.shape[2] or not np.any(dq) or np.any(dq[k:]):
        return None
    prev = history[-2::-1]
    x, p = x_last, p_last.copy()
    if prev:
        d = np.column_stack([h[0] - q_last for h in prev])
        c = np.linalg.lstsq(d, dq, rcond=PREDICTOR_RCOND)[0]
        if not (np.all(np.isfinite(c)) and np.abs(c).sum() <= PREDICTOR_MAX_WEIGHT):
            c = np.zeros(len(prev))
        x, p = _secant(prev, c, x_last, p_last)
        dq = dq - d @ c
    vc = np.asarray(load.volume_controlled, bool)
    dp = dq[:k].copy()
    with np.errstate(divide="ignore", invalid="ignore"):
        if load.ratio is not None:  # together: dp = r dlambda, r.dV = the growth's change
            r = np.asarray(load.ratio, float)
            dp = r * float(r @ dq[:k]) / float(r @ compliance @ r)
        elif vc.any():
            rest = dq[:k][vc] - compliance[np.ix_(vc, ~vc)] @ dp[~vc]
            try:
                dp[vc] = np.linalg.solve(compliance[np.ix_(vc, vc)], rest)
            except np.linalg.LinAlgError:
                return None
    if not np.all(np.isfinite(dp)):
        return None
    return x + sens @ dp, p + np.where(vc, dp, 0.0)


def _moments(d: np.ndarray, order: int) -> np.ndarray:
    """(monomials, columns): every degree-`order` monomial of each column of d."""
    return np.prod(d[_monomial_rows(d.shape[0], order)], axis=1)


@functools.lru_cache(maxsize=64)
def _monomial_rows(n: int, order: int) -> np.ndarray:
    """(monomials, order) row indices of every degree-`order` monomial of n variables."""
    return np.array(
        list(itertools.combinations_with_replacement(range(n), order)), np.int64
    ).reshape(-1, order)


def _moment_weights(d: np.ndarray, dq: np.ndarray):
    """Weights c (see `_history_guess`) with d c = dq (to 1e-6 relative), then, order by
    order up to PREDICTOR_ORDER, the least-squares match of sum_j c_j d_j^(x k) =
    dq^(x k) (d_j the columns of d) among the weights the lower orders leave free; the
    highest order whose weights stay bounded (PREDICTOR_MAX_WEIGHT for the first,
    QUADRATIC_MAX_WEIGHT above), or None."""
    live = np.flatnonzero(np.any(d, axis=1) | (dq != 0))  # load components that vary
    scale = float(np.linalg.norm(dq))
    d, dq = d[live] / scale, dq[live] / scale
    c, free, best = np.zeros(d.shape[1]), np.eye(d.shape[1]), None
    for order in range(1, PREDICTOR_ORDER + 1):
        if free.shape[1] == 0:
            break
        a = _moments(d, order)
        target = _moments(dq[:, None], order)[:, 0]
        u, sv, vt = np.linalg.svd(a @ free)
        rank = int(np.sum(sv > PREDICTOR_RCOND * sv[0])) if len(sv) and sv[0] > 0 else 0
        y = vt[:rank].T @ ((u[:, :rank].T @ (target - a @ c)) / sv[:rank])
        c, free = c + free @ y, free @ vt[rank:].T
        if order == 1 and np.linalg.norm(d @ c - dq) > 1e-6:
            return None
        bound = PREDICTOR_MAX_WEIGHT if order == 1 else QUADRATIC_MAX_WEIGHT
        if np.all(np.isfinite(c)) and np.abs(c).sum() <= bound:
            best = c
        elif order > 1:
            break
    return best


def impose_prescribed(model, x: np.ndarray, load: Load) -> np.ndarray:
    """x with the prescribed dofs (moved [[fixed]] regions) at rest + load.prescribed *
    displacement (a copy when anything is prescribed)."""
    if not len(model.prescribed_dofs):
        return x
    x = np.array(x, float)
    flat = x.reshape(-1)
    flat[model.prescribed_dofs] = (
        model.rest.reshape(-1)[model.prescribed_dofs] + load.prescribed * model.prescribed_mm
    )
    return x


LIFT_FRACTION = 1e-3
"""`_lift_prescribed` measures the forces of the prescribed motion over this fraction of
it (small enough to stay linear and invert nothing)."""


def _lift_prescribed(model, solver, x: np.ndarray, load_a: Load, load_b: Load) -> np.ndarray:
    """Start of a load step that moves prescribed dofs: the free dofs follow the motion
    by one linear solve with the tangent at x, K_ff dx_f = -K_fp dx_p (K_fp dx_p from
    the forces over LIFT_FRACTION of the motion), so that moving a clamp inverts no
    element next to it. x itself when nothing moves."""
    dp = (load_b.prescribed - load_a.prescribed) * model.prescribed_mm
    if not np.any(dp):
        return x
    free = model.pattern.free
    kin = model.kinematics(x)
    f0 = model.forces_and_energy(kin[0], kin[1])[0].reshape(-1)[free].copy()
    xe = np.array(x, float)
    xe.reshape(-1)[model.prescribed_dofs] += LIFT_FRACTION * dp
    kin_e = model.kinematics(xe)
    f1 = model.forces_and_energy(kin_e[0], kin_e[1])[0].reshape(-1)[free]
    kin = model.kinematics(x)
    solver.update(kin[1], kin[0], None, True)
    dx = solver.solve(-(f1 - f0) / LIFT_FRACTION)
    out = np.array(x, float)
    out.reshape(-1)[free] += dx
    out.reshape(-1)[model.prescribed_dofs] += dp
    return out


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


def _result(model: FemModel, x, p, iterations, merit, subdivisions, t0, det_f=None) -> StateResult:
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


def _reference_force(model: FemModel, x, p, load_a: Load, load_b: Load, floor: float) -> float:
    """Force scale of a load step: the largest of the external loads at both ends (the
    elastic force at the start joins it at the step's first evaluation) (mN)."""
    free = model.pattern.free
    h = model.chamber_gradients(x) if len(model.chamber_tris) else None
    fa = model.external_forces(x, p, load_a, h).reshape(-1)[free]
    pb = p.copy()
    if len(pb):
        pb[~load_b.volume_controlled] = load_b.pressure_kpa[~load_b.volume_controlled]
    fb = model.external_forces(x, pb, load_b, h).reshape(-1)[free]
    return max(np.linalg.norm(fa), np.linalg.norm(fb), floor)
