"""The start of the next state from the states already converged on a model's linear
solver (its `history`): the secant over the kept states, matching the load's moments up to
PREDICTOR_ORDER (`history_guess`), or, while they are too few, the first state's
response to each chamber's pressure (`remember_sensitivity`, `sensitivity_guess`).
Newton retries from the plain start when a guess fails."""

from __future__ import annotations

import functools
import itertools

import numpy as np

from fruitcli.errors import SolverError
from fruitcli.fem.fem_model import FemModel, Kept, LinearSolver
from fruitcli.fem.state_load import Load

HISTORY_STATES = 16
"""Converged states kept (on the linear solver) for the predictor of the next: with 10,
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


def remember(history: list[Kept], q: np.ndarray, x: np.ndarray, p: np.ndarray) -> list[Kept]:
    """The kept states with (q, x, p) appended, an earlier state of the same load q
    dropped (a repeated load, e.g. an animation closing its cycle, would otherwise take
    two of the HISTORY_STATES slots and leave too few distinct loads for the
    second-order guess), and the oldest dropped beyond HISTORY_STATES."""
    kept = [h for h in history if not np.array_equal(h[0], q)]
    return (kept + [(q, x, p)])[-HISTORY_STATES:]


def load_vector(load: Load) -> np.ndarray:
    """The load as one vector: pressures (or volume growths where volume controlled),
    gravity, jig scale, and which chambers are volume controlled (1.0 or 0.0: a change
    of control mode makes the secant meaningless, see `history_guess`)."""
    vc = np.asarray(load.volume_controlled, bool)
    return np.concatenate(
        [
            np.where(vc, load.volume_growth_mm3, load.pressure_kpa),
            [load.gravity, load.jig, load.prescribed],
            vc.astype(float),
        ]
    )


def history_guess(
    history: list[Kept], x_start: np.ndarray | None, load: Load
) -> tuple[np.ndarray, np.ndarray] | None:
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
    q = load_vector(load)
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


def _secant(
    prev: list[Kept], c: np.ndarray, x_last: np.ndarray, p_last: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(x_last + sum_j c_j (x_j - x_last), the same of the pressures) over the kept states
    prev (load vector, x, p) with weights c."""
    x = x_last + sum(cj * (h[1] - x_last) for cj, h in zip(c, prev, strict=True))
    p = p_last + sum(cj * (h[2] - p_last) for cj, h in zip(c, prev, strict=True))
    return x, p


SENSITIVITY_RTOL = 1e-2
"""Relative residual of the solves K dx/dp_k = dH_k^T of `remember_sensitivity`: they
only start Newton, which the tangent's own staleness already limits to first order."""


def remember_sensitivity(
    model: FemModel, solver: LinearSolver, x: np.ndarray, load: Load, iterations: int
) -> None:
    """Keep on the solver, at the first converged state x, (dx/dp (n, 3, K), C (K, K)):
    the nodes' response to each chamber's pressure, K^-1 H_k^T with the solver's current
    tangent (one CG solve per chamber, counted in this state's time and the solver's
    stats), and the chambers' volume compliance C = H dx/dp (mm^3/kPa).
    `sensitivity_guess` starts the next states with it while the history is too short
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


def sensitivity_guess(
    solver: LinearSolver, x_start: np.ndarray | None, load: Load
) -> tuple[np.ndarray, np.ndarray] | None:
    """Start of the next state when `history_guess` has none: the kept states' secant as
    far as they span the load change (least squares, bounded weights), the rest through
    the first state's dx/dp (`remember_sensitivity`): a pressure-controlled chamber's
    pressure change directly, a volume-controlled one's volume change through the
    pressure change dp_v = C_vv^-1 (dV_v - C_vp dp_p) that makes it (chambers together
    along ratios r: dp = r (r.dV) / (r C r)). Only when x_start is the last state kept
    and nothing but the chambers' pressures or volumes changed; None otherwise."""
    kept = solver.sensitivity
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
    dq = load_vector(load) - q_last
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


def _moment_weights(d: np.ndarray, dq: np.ndarray) -> np.ndarray | None:
    """Weights c (see `history_guess`) with d c = dq (to 1e-6 relative), then, order by
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
