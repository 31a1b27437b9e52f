"""Newton on one load step (the paper's eqs. 2-3): iterations on the consistent
corotational tangent (with the follower-pressure stiffness; the projected or SOFA's
warped tangent when a step fails, see TANGENTS) with chamber pressures as Lagrange
multipliers, an inexact linear solve (Eisenstat-Walker, chord steps near the
tolerance), a backtracking line search, and the convergence tests (the residual, a
round-off stall, the kept factor's displacement estimate).

Residual r = f_ext(x, p) - f_int(x) over the free dofs; a volume-controlled chamber
adds the constraint V(x) = V_rest + growth with its pressure p as unknown. The linear
system [K  -H^T; H  0] is solved by the Schur complement W = H K^-1 H^T (mm^3/kPa).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from fruitcli.errors import SolverError
from fruitcli.fem.fem_model import FemModel, LinearSolver
from fruitcli.fem.solver.options import OutOfTime, SolverOptions, Stalled
from fruitcli.fem.state_load import Load
from fruitcli.fem.tolerances import (
    ARMIJO,
    CHORD_CONTRACTION,
    ESTIMATE_SAFETY,
    ESTIMATE_WINDOW,
    LINE_SEARCH_STEPS,
    LINEAR_DISPLACEMENT_SHARE,
    LINEAR_MARGIN,
    MIN_DET_F,
    PCG_RELATIVE_TOLERANCE,
    PCG_TARGET,
    STALL_CUT,
    STALL_FAR,
    STALL_RESIDUAL_FACTOR,
    STEP_TOLERANCE,
)


class Iterate(NamedTuple):
    """An iterate evaluated at (x, p) (`NewtonStep.evaluate`): what a Newton step reads
    of it."""

    rot: np.ndarray  # the model's kinematics the tangent is built at (`kinematics`)
    det_f: np.ndarray  # volume ratio J per element (or its smallest over the element)
    h: np.ndarray  # (K, n, 3) chamber volume gradients dV/dx (mm^2); K = 0 without chambers
    r: np.ndarray  # (n_free,) residual force f_ext - f_int over the free dofs (mN)
    g: np.ndarray  # (kv,) controlled volume error c V - target (mm^3)
    merit: float  # relative residual (force over its scale, or the volume error)
    energy: float  # potential energy, strain minus external work (mN mm); nan: inverted
    f: np.ndarray  # the model's deformation state the tangent is built at


class NewtonStep:
    """Newton on one load step; holds the work arrays of the current iterate."""

    def __init__(self, model: FemModel, solver: LinearSolver, load: Load, ref: float):
        self.m, self.solver, self.load, self.ref = model, solver, load, ref
        self.vc = np.flatnonzero(load.volume_controlled)
        # the controlled volumes c V (one row per constraint; p moves along c^T):
        # each volume-controlled chamber, or the chambers together (`Load.together`)
        k = len(load.volume_controlled)
        self.c = np.eye(k)[self.vc] if load.ratio is None else load.ratio[None, :]
        self.v_target = self.c @ (model.chamber_rest_volume_mm3 + load.volume_growth_mm3)
        self.v_ref = np.maximum(np.abs(self.c) @ model.chamber_rest_volume_mm3, 1.0)
        self.f_int_norm = 0.0
        # time.perf_counter() past which Newton stops (OutOfTime; s)
        self.deadline: float | None = None
        # whether the start's evaluation brings the tangent along (`evaluate`)
        self.tangent_at_start = True
        # whether the second Newton step's tangent is factored afresh (`iterate`)
        self.refactor_second = False
        # report(iteration, merit) when progress is asked for
        self.report: Callable[[int, float], None] | None = None

    def evaluate(self, x: np.ndarray, p: np.ndarray, tangent: bool = False) -> Iterate:
        """The iterate at x (n, 3) mm with chamber pressures p (K,) kPa; with
        `tangent`, the model evaluates the element tangents in the same pass (a load
        step's start, whose tangent Newton's first step needs: on the quadratic default
        Fruit one element loop of 60-100 ms instead of that and a forces loop of 9-14
        ms; trial iterates do not, as a tangent evaluated for an iterate that then
        converges costs far more than the forces loop it would save)."""
        m = self.m
        f, rot, det_f = m.kinematics(x, tangent)
        h = m.chamber_gradients(x) if m.chamber_tris else np.zeros((0, m.n_nodes, 3))
        f_int, energy = m.forces_and_energy(f, rot)
        r = m.external_forces(x, p, self.load, h) - f_int
        r = r.reshape(-1)[m.pattern.free]
        energy += m.external_potential(x, p, self.load)
        g = self.c @ m.chamber_volumes(x) - self.v_target if len(self.vc) else np.zeros(0)
        # scale: the step's load, or the elastic force once it is larger (volume
        # control starts with an unknown pressure and no external load)
        self.f_int_norm = float(np.linalg.norm(f_int.reshape(-1)[m.pattern.free]))
        scale = max(self.ref, self.f_int_norm)
        merit = float(np.linalg.norm(r)) / scale
        if len(g):
            merit = max(merit, float(np.max(np.abs(g) / self.v_ref)))
        return Iterate(rot, det_f, h, r, g, merit, energy, f)

    def direction(
        self, x: np.ndarray, p: np.ndarray, now: Iterate, level: int, keep_tangent: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """Newton direction (dx over the free dofs (n_free,) mm, dp (K,) kPa) at the
        iterate `now` with the tangent of `level` (see TANGENTS), or with the solver's
        current tangent when `keep_tangent` (a chord step)."""
        m = self.m
        if keep_tangent:
            pass  # chord step: the solver keeps the tangent of the previous step
        elif TANGENTS[level] == "warped":
            self.solver.update(now.rot)
        else:
            exact = TANGENTS[level] == "exact"
            # assembled (about 1.5 ms here): a CSR product then costs next to nothing
            load_k = m.load_stiffness(x, p) if exact else None
            self.solver.update(now.rot, now.f, load_k, not exact)
        if not len(self.vc):
            return self.solver.solve(now.r), np.zeros(len(p))
        hv = (self.c @ now.h.reshape(len(self.c[0]), -1))[:, m.pattern.free]  # (kv, n_free)
        sol = self.solver.solve(np.column_stack([now.r, hv.T]))
        kr, kh = sol[:, 0], sol[:, 1:]
        w = hv @ kh  # compliance dV/dp (mm^3/kPa)
        dp = np.linalg.solve(w, -now.g - hv @ kr)
        return kr + kh @ dp, self.c.T @ dp


TANGENTS = ("exact", "projected", "warped")
"""Tangents tried in turn when a Newton step fails: the consistent one (rotation term and
follower-pressure stiffness; quadratic convergence near equilibrium), then without the
follower-pressure stiffness and with each element's rotation term clamped to positive
semi-definite (Teran 2005; positive definite, so a descent direction), then SOFA's
warped R K0 R^T (robust far from equilibrium, linear convergence). The consistent one
is skipped while an element is inverted or flat."""

SAFEST = len(TANGENTS) - 1
"""The level of the last tangent tried (`TANGENTS`)."""


def iterate(
    step: NewtonStep, x: np.ndarray, p: np.ndarray, options: SolverOptions
) -> tuple[bool, np.ndarray, np.ndarray, int, float, np.ndarray]:
    """Newton from x (n, 3) mm and chamber pressures p (K,) kPa to the equilibrium of the
    step's load: (converged, x, p, iterations, relative residual, det F per element).
    Each iteration: the convergence tests, the linear tolerance (`_ask_linear_solve`),
    the direction with the tangent of `level` (the next, safer one when a tangent has
    no factor or gives no descent), and a line search along it (`_line_search`)."""
    m = step.m
    now = step.evaluate(x, p, step.tangent_at_start)
    if not np.isfinite(now.energy):  # an element inverted at the start (hyperelastic model)
        return False, x, p, 0, np.inf, now.det_f
    step.ref = max(step.ref, step.f_int_norm)  # the elastic force at the start counts
    level = 0  # index into TANGENTS; raised for one step when a step fails
    chord = False  # whether the last step kept the tangent
    merits = []  # the relative residual at each iterate
    for it in range(options.max_iterations + 1):
        if now.merit <= options.tolerance or _close_enough(step, now.r, now.merit, options):
            return True, x, p, it, now.merit, now.det_f
        if it == options.max_iterations:
            break
        merits.append(now.merit)
        _check_stall(merits, options)
        # not a step whose tangent's factorization (as long as the solver's last) would
        # end past the deadline
        _check_time(step, step.solver.factor_seconds)
        if step.report is not None:
            step.report(it, now.merit)
        if level == 0 and now.det_f.min() <= MIN_DET_F:
            level = SAFEST
        last_merit = merits[-2] if it else np.inf
        near = _chord_step(step, it, level, chord, now.merit, last_merit, options)
        chord = near
        if it == 1 and step.refactor_second and hasattr(step.solver, "refresh"):
            step.solver.refresh = True  # a load step from rest: its first step moved far
        _ask_linear_solve(step, it, now.merit, near, options)
        try:
            dx_free, dp = step.direction(x, p, now, level, keep_tangent=near)
        except SolverError:
            if level < SAFEST:  # no factor of this tangent (singular): the next, safer one
                level += 1
                continue
            raise
        finally:
            step.solver.displacement_goal = (0.0, 1.0)  # Newton's steps only
        if _stalled(step, now.merit, dx_free, options):
            return True, x, p, it, now.merit, now.det_f  # round-off: the correction is nil
        if not len(step.vc) and level < SAFEST and not float(now.r @ dx_free) > 0.0:
            level += 1  # not a descent direction: indefinite tangent
            continue
        alpha, x_new, p_new, trial = _line_search(step, x, p, now, dx_free, dp, it)
        if trial is None or alpha == 0.0:
            if level < SAFEST:
                level += 1
                continue
            return False, x, p, it + 1, now.merit, now.det_f if trial is None else trial.det_f
        # a damped step says the tangent models the energy poorly here: take the next,
        # safer tangent until a full step is accepted again
        damped_escalates = m.escalate_on_damping
        level = 0 if alpha == 1.0 or not damped_escalates else min(level + 1, SAFEST)
        x, p = x_new, p_new
        merit = now.merit
        if it == 0 and alpha == 1.0 and merit > 0 and trial.merit > 3.0 * step.solver.rtol * merit:
            step.solver.newton_c = trial.merit / merit**2  # nonlinear part dominates: observe C
        now = trial
    return False, x, p, options.max_iterations, now.merit, now.det_f


def _chord_step(
    step: NewtonStep,
    it: int,
    level: int,
    chord: bool,
    merit: float,
    last_merit: float,
    options: SolverOptions,
) -> bool:
    """Whether Newton step `it` keeps the tangent of the step before (a chord step):
    near the tolerance (within the solver's `near_tolerance` factor, 0 = never) the last
    step only has to cross it, so the linear solve may be as loose as the goal asks and
    the previous tangent will do; only right after a step in Newton's quadratic regime
    (`merit` at most CHORD_CONTRACTION times `last_merit`), with the exact tangent
    (`level` 0), and never twice in a row (`chord`: the step before was one). Never as
    the second step of a load step along loose ones (`refactor_second`): its first
    removed the bulk error of the step's start, not the quadratic regime's, and the
    refactorization it asks for would be skipped (the default Fruit under its weight,
    `curve_start.start_state`: 10 Newton steps with that chord step, 8 without)."""
    return (
        it > 0
        and level == 0
        and not chord
        and not (it == 1 and step.refactor_second)
        and merit <= CHORD_CONTRACTION * last_merit
        and merit <= step.solver.near_tolerance * options.tolerance
    )


def _ask_linear_solve(
    step: NewtonStep, it: int, merit: float, near: bool, options: SolverOptions
) -> None:
    """Set the solver's relative tolerance (and displacement goal) for Newton step `it`
    at relative residual `merit`. Inexact Newton (Eisenstat-Walker): solve no more
    exactly than the nonlinear residual this step will leave, C merit^2 (C observed on
    earlier full steps; the first iteration of a step only: later ones converge less
    regularly), never looser than PCG_RELATIVE_TOLERANCE (PCG_TARGET on a chord step,
    `near`). With a displacement tolerance, CG also stops once the factor estimates its
    error (mm) within a share of what `_close_enough` accepts, with a residual within
    that share of the window where it is asked (pressure control only)."""
    goal = PCG_TARGET * options.tolerance
    if it == 0:
        goal = max(goal, LINEAR_MARGIN * step.solver.newton_c * merit**2)
    cap = PCG_TARGET if near else PCG_RELATIVE_TOLERANCE
    step.solver.rtol = min(cap, max(goal / max(merit, 1e-300), 1e-12))
    if options.displacement_tolerance_mm > 0.0 and not len(step.vc):
        share = LINEAR_DISPLACEMENT_SHARE
        step.solver.displacement_goal = (
            share * options.displacement_tolerance_mm / ESTIMATE_SAFETY,
            share * ESTIMATE_WINDOW * options.tolerance / max(merit, 1e-300),
        )


def _stalled(step: NewtonStep, merit: float, dx_free: np.ndarray, options: SolverOptions) -> bool:
    """A round-off stall counted as converged: the relative residual within
    STALL_RESIDUAL_FACTOR of the tolerance and the full Newton correction dx_free (mm)
    moving no node by more than STEP_TOLERANCE times the body size."""
    return bool(
        merit <= STALL_RESIDUAL_FACTOR * options.tolerance
        and np.abs(dx_free).max(initial=0.0) <= STEP_TOLERANCE * step.m.extent_mm
    )


def _line_search(
    step: NewtonStep,
    x: np.ndarray,
    p: np.ndarray,
    now: Iterate,
    dx_free: np.ndarray,
    dp: np.ndarray,
    it: int,
) -> tuple[float, np.ndarray, np.ndarray, Iterate | None]:
    """Backtracking along the Newton direction (dx_free over the free dofs, mm; dp, kPa)
    from (x, p) at the iterate `now`, halving the step up to LINE_SEARCH_STEPS times:
    (alpha, x, p, trial) of the step accepted, or alpha 0.0 with the last trial
    evaluated (None if none was) when none is. A step is refused when it changes an
    element's volume ratio by more than the model's `dilatation_step`, inverts or
    flattens an element (MIN_DET_F) or is not finite; accepted on sufficient decrease
    of the energy (Armijo; pressure control), on a lower residual, or, for volume
    control, as the first full step of a load step that lowers the volume error."""
    m = step.m
    flat = np.zeros(3 * m.n_nodes)
    flat[m.pattern.free] = dx_free
    dx = flat.reshape(-1, 3)
    alpha, trial = 1.0, None
    j_limit = m.dilatation_step
    j_now = np.abs(m.mean_dilatation(x) - 1.0) if j_limit else np.zeros(0)
    for _ in range(LINE_SEARCH_STEPS):
        xt, pt = x + alpha * dx, p.copy()
        pt += alpha * dp
        if j_limit and np.any(np.abs(m.mean_dilatation(xt) - 1.0) > j_now + j_limit):
            alpha *= 0.5  # a spurious dilatation (see continuum.DILATATION_STEP)
            continue
        _check_time(step)
        trial = step.evaluate(xt, pt)
        if not (np.isfinite(trial.merit) and trial.det_f.min() > MIN_DET_F):
            alpha *= 0.5
            continue
        descent = len(step.vc) == 0 and (
            trial.energy <= now.energy - ARMIJO * alpha * float(now.r @ dx_free)
        )
        # volume control: a step's first full Newton step meets the volume but (a
        # nearly incompressible body's bulk term weighing its second-order part)
        # leaves a force residual above the volume error it started from; take it
        descent = descent or (
            len(step.vc) > 0
            and it == 0
            and alpha == 1.0
            and np.abs(trial.g).max() < np.abs(now.g).max()
        )
        if descent or trial.merit < now.merit:
            return alpha, xt, pt, trial
        alpha *= 0.5
    return 0.0, x, p, trial


def _check_stall(merits: list[float], options: SolverOptions) -> None:
    """Raise Stalled when the last options.stall_steps Newton steps cut the relative
    residual (`merits`, one per iterate) by less than STALL_CUT in all, the residual
    still above STALL_FAR times the tolerance."""
    n = options.stall_steps
    if n <= 0 or len(merits) <= n or merits[-1] <= STALL_FAR * options.tolerance:
        return
    if merits[-1] > (1.0 - STALL_CUT) * merits[-1 - n]:
        raise Stalled(
            f"Newton stalled at a relative residual of {merits[-1]:.2e} ({n} steps cut "
            f"it by {1.0 - merits[-1] / merits[-1 - n]:.0%})"
        )


def _check_time(step: NewtonStep, ahead: float = 0.0) -> None:
    """Raise OutOfTime when the step's deadline is less than `ahead` seconds away:
    checked before each Newton step's tangent (`ahead` one factorization) and each
    line-search evaluation (0), so that a state overruns its budget by little more than
    a factorization that takes longer than the last one."""
    if step.deadline is not None and time.perf_counter() + ahead > step.deadline:
        raise OutOfTime("time budget", 0.0)


def _close_enough(step: NewtonStep, r: np.ndarray, merit: float, options: SolverOptions) -> bool:
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
