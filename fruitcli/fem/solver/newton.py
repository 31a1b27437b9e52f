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

import numpy as np

from fruitcli.errors import SolverError
from fruitcli.fem.corotational_model import Load
from fruitcli.fem.fem_model import FemModel
from fruitcli.fem.solver.linsolve import TangentSolver
from fruitcli.fem.solver.options import OutOfTime, SolverOptions
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
    STALL_RESIDUAL_FACTOR,
    STEP_TOLERANCE,
)

Evaluation = tuple[
    np.ndarray, np.ndarray, np.ndarray | None, np.ndarray, np.ndarray, float, float, np.ndarray
]
"""(rot, det_f, h, r, g, merit, energy, f) of an iterate (`NewtonStep.evaluate`)."""


class NewtonStep:
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

    def evaluate(self, x, p, tangent: bool = False) -> Evaluation:
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

    def direction(
        self, x, p, rot, h, r, g, f, level, keep_tangent=False
    ) -> tuple[np.ndarray, np.ndarray]:
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


def iterate(
    step: NewtonStep, x, p, options: SolverOptions
) -> tuple[bool, np.ndarray, np.ndarray, int, float, np.ndarray]:
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
