"""Limit pressures of a body's chambers: each chamber's pressure-volume curve followed
under volume control (the chamber's volume is the load, its pressure the unknown Lagrange
multiplier, as `[actuation].volume_growth_mm3` does), one chamber at a time with the
others at rest (pressure 0).

- Inflation: the pressure rises, peaks at the limit pressure (the largest pressure the
  chamber holds: pressure control has no equilibrium above it) and falls; the curve is
  followed until it has fallen for FALL_STEPS steps, and the peak is the vertex of the
  parabola through the largest sample and its neighbours (with one fall step, as `fruit
  limits` follows it, the curve may end before its peak at the vertex just ahead of its
  last three samples: `PEAK_AHEAD`).
- Suction: the pressure falls (below 0) while the cavity shrinks, until its walls would
  meet (self-contact is not modelled): the volume under COLLAPSE_VOLUME of its rest
  volume or the next sample's below it, an element at the wall about to invert (det F
  under COLLAPSE_DET_F), the pressure turning back towards 0 (the wall buckling in) or
  no equilibrium; the collapse pressure is the lowest pressure reached.

Steps are uniform in the chamber's mean stretch s = (V / V0)^(1/3) (the inner stretch
of a spherical cavity), shorter near an inflation's peak (`_next_step`). The curves of a
body start from its equilibrium under its weight (`curve_start.start_state`). Units: mm,
mm^3, kPa.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from fruitcli.errors import SolverError
from fruitcli.fem.curve_peak import MAX_STRETCH, PEAK_AHEAD, PEAK_RISE, peak, refusing_bound, vertex
from fruitcli.fem.curve_start import (
    Chambers,
    chamber_index,
    chamber_load,
    first_kept_or_solved,
    first_sample,
    pressure_along,
    ratio_of,
    refuses_at_once,
)
from fruitcli.fem.fem_model import FemModel, LinearSolver
from fruitcli.fem.linear_response import Start
from fruitcli.fem.sample_cache import SampleCache, kept_or_solved
from fruitcli.fem.solver.options import OutOfTime, SolverOptions, Stalled, StateResult
from fruitcli.fem.solver.state import solve_state
from fruitcli.fem.state_load import Load

TOGETHER = "together"
"""The name of the curve of the chambers inflated together (`follow` with ratios)."""

STRETCH_STEP = 0.1
"""Step of the mean stretch (V / V0)^(1/3) between samples of a curve: the thick
sphere's peak (at stretch 1.83) comes out of the parabola within 0.1 % of the densely
sampled curve's."""

FALL_STEPS = 2
"""Samples below the largest pressure that end an inflation curve (past its peak)."""

MIN_STRETCH = 0.45
"""Suction is followed down to this mean stretch (9.1 % of the rest volume: the walls of
a flat chamber are about to meet)."""

COLLAPSE_VOLUME = MIN_STRETCH**3
"""A cavity under this fraction of its rest volume counts as collapsed."""

COLLAPSE_DET_F = 0.2
"""An element compressed under this volume ratio counts as the walls meeting."""


@dataclass
class ChamberCurve:
    """One chamber's pressure-volume samples (growth over the rest volume, mm^3; kPa)
    and what they give: the limit pressure and the growth there (inflation), the
    collapse pressure (suction), each None when the range followed does not reach it;
    `end` says why the curve stopped."""

    name: str
    rest_volume_mm3: float
    growth_mm3: list[float] = field(default_factory=list)
    pressure_kpa: list[float] = field(default_factory=list)
    limit_pressure_kpa: float | None = None
    limit_growth_mm3: float | None = None
    collapse_pressure_kpa: float | None = None
    end: str = ""
    limit_bound_kpa: float | None = None  # an upper bound of the limit (`levels_off_bound`)
    collapse_bound_kpa: float | None = None  # a lower bound of the collapse (`levels_off_bound`)
    failed: bool = False  # the curve ended without equilibrium at its next sample


def _next_step(
    model: FemModel, curve: ChamberCurve, stretches: list[float], step: float, fall_steps: int
) -> float | None:
    """(the next inflation step, or None to end the curve at an extrapolated limit):
    with the parabola through the last three samples peaking behind the last one
    (sample i the largest), half a step (a sample just past the peak brackets it); peaking
    within PEAK_AHEAD steps ahead and PEAK_RISE above it, None after setting the curve's
    limit there (neo-Hookean; curves that end FALL_STEPS or more past the peak go on);
    within a step ahead, the step to the vertex; otherwise `step`."""
    top = vertex(np.array(stretches), np.array(curve.pressure_kpa))
    p = curve.pressure_kpa[-1]
    if top is None or p < max(curve.pressure_kpa):
        return step
    ahead = top[0] - stretches[-1]
    if ahead <= 0:
        return step / 2
    if (
        ahead <= PEAK_AHEAD * step
        and top[1] - p <= PEAK_RISE * abs(p)
        and fall_steps < FALL_STEPS
        and model.material_name == "neo-hookean"
    ):
        curve.limit_pressure_kpa = top[1]
        curve.limit_growth_mm3 = curve.rest_volume_mm3 * (top[0] ** 3 - 1.0)
        curve.end = "at the limit point (the vertex of the last three samples' parabola)"
        return None
    return min(step, max(ahead, step / 4))


def follow(
    model: FemModel,
    k: Chambers,
    direction: int = 1,
    *,
    solver: LinearSolver | None = None,
    options: SolverOptions | None = None,
    stop_beyond_kpa: float | None = None,
    step: float = STRETCH_STEP,
    deadline: float | None = None,
    fall_steps: int = FALL_STEPS,
    budget: tuple[float, float] | None = None,
    stop_at_asked: bool = True,
    halvings: int = 0,
    beyond: tuple | None = None,
    progress: Callable[[str], None] | None = None,
    start: Start | None = None,
    samples: SampleCache | None = None,
    slope_at_rest: float | None = None,
) -> ChamberCurve:
    """Chamber k's curve from rest (k an int; or the chambers together along pressure
    ratios k, (K,), `Load.together`: the curve's pressure is then the largest chamber
    pressure and its volume growth that of sum_k ratio_k V_k): inflation (direction 1) up
    to MAX_STRETCH or past the limit, suction (direction -1) down to MIN_STRETCH or the
    collapse. With `stop_beyond_kpa`, it stops as soon as the pressure passes that value
    (reachable: neither a limit nor a collapse before it); without `stop_at_asked`, only
    a curve that levels off short of it ends there (`_levels_off`). `fall_steps`: samples past
    the peak (inflation) or the lowest pressure (suction) that end the curve. `deadline`
    (time.monotonic()) ends the curve where it is; `budget` (factor, floor) caps each
    sample after the first (default STEP_BUDGET). A sample after the first that finds no
    equilibrium is tried again up to `halvings` times, each time half as far from the
    last sample (the step stays shorter afterwards). `beyond` = (budget, halvings): those
    of the samples after the pressure passed `stop_beyond_kpa` (a check going on to the
    limit as `fruit limits` does). `progress(msg)` is told each sample. `start`: the
    `Start` the first sample comes from (`curve_start.start_state`, shared among the
    curves of a body); without it, from rest (`curve_start.first_sample`). `samples`:
    where kept samples come from and solved ones go (`SampleCache`). `slope_at_rest`:
    dp/ds at rest (`curve_peak.rest_slope`), for a bound after the first sample. The
    loop stays in one piece: the step, the budget and the halvings left pass from each
    sample to the next."""
    r = ratio_of(model, k)
    alone = chamber_index(k)
    name = model.chamber_names[alone] if alone is not None else TOGETHER
    v0 = float(r @ model.chamber_rest_volume_mm3)
    curve = ChamberCurve(name, v0, [0.0], [0.0])
    budget = budget or STEP_BUDGET
    solver = _curve_solver(model, solver, options)
    options = options or SolverOptions(load_steps=1)
    stretches = [1.0]
    last = None  # s: the longest sample so far (the next one's budget, STEP_BUDGET)
    x, prev, p_start = None, None, None
    s, ds = 1.0, step  # ds: the next step (shorter near an inflation's peak, `_next_step`)
    while True:
        s = s + direction * ds
        if _out_of_range(curve, s, step, direction, stretches, deadline):
            break
        growth = v0 * (s**3 - 1.0)
        load = chamber_load(model, alone, growth) if alone is not None else Load.together(r, growth)
        try:
            if x is None or p_start is None or last is None:  # all three set together
                first = functools.partial(
                    first_sample, model, k, r, start, load, growth, solver=solver, name=name
                )
                screen = _screen(model, r, s, direction, stop_beyond_kpa, slope_at_rest)
                res = first_kept_or_solved(
                    model, samples, load, solver, name, first, options, screen
                )
            else:  # from the last sample
                opts = _sample_options(options, last, budget)
                solve = functools.partial(
                    solve_state, model, load, x, prev, p_start, opts, solver, f"chamber {name}"
                )
                res = kept_or_solved(samples, load, solver, solve)
        except SolverError as exc:
            if halvings > 0 and last is not None:
                halvings -= 1
                s, step = stretches[-1], ds / 2
                ds = step
                if progress:
                    progress(f"limits: chamber {name}: no equilibrium; a step of {step:.3g}")
                continue
            _no_equilibrium(curve, exc, s, direction)
            break
        x, prev, p_start = res.x, load, res.pressure_kpa
        last = max(last or 0.0, res.solve_ms / 1e3)
        stretches.append(s)
        if direction > 0 and len(stretches) >= 3:
            _start_from_last(solver)
        p = _record(curve, res, r, progress)
        passed = stop_beyond_kpa is not None and direction * (p - stop_beyond_kpa) >= 0
        if passed and stop_at_asked:
            curve.end = f"the pressure asked ({stop_beyond_kpa:g} kPa)"
            break
        if passed and beyond is not None:
            (budget, halvings), beyond = beyond, None
        if _levels_off(model, curve, stretches, direction, stop_beyond_kpa, slope_at_rest):
            break
        if _turned(model, curve, stretches, res, direction, fall_steps):
            break
        ds = step
        if direction > 0 and len(stretches) >= 4:
            shorter = _next_step(model, curve, stretches, step, fall_steps)
            if shorter is None:
                break
            ds = shorter
    return curve


def _screen(
    model: FemModel,
    r: np.ndarray,
    s: float,
    direction: int,
    asked: float | None,
    slope_at_rest: float | None,
) -> Callable[[StateResult], bool] | None:
    """Whether a curve's first sample at mean stretch `s` refuses the pressure `asked`
    (kPa) at once (`curve_start.refuses_at_once`, with the slope at rest), as a function
    of the sample; None without a pressure asked or a slope at rest."""
    if asked is None or slope_at_rest is None:
        return None
    return functools.partial(refuses_at_once, model, r, s, asked, _end(direction), slope_at_rest)


def _end(direction: int) -> float:
    """The mean stretch a curve's bound is continued to: MAX_STRETCH for an inflation
    (direction 1), MIN_STRETCH for a suction (-1)."""
    return MAX_STRETCH if direction > 0 else MIN_STRETCH


def _record(
    curve: ChamberCurve,
    res: StateResult,
    r: np.ndarray,
    progress: Callable[[str], None] | None,
) -> float:
    """Add a solved sample `res` to `curve` (volume growth mm^3 and pressure kPa along
    the ratios `r`), tell `progress`; -> its pressure (kPa)."""
    volume = float(r @ res.chamber_volume_mm3)
    p = pressure_along(res, r)
    curve.growth_mm3.append(volume - curve.rest_volume_mm3)
    curve.pressure_kpa.append(p)
    if progress:
        how = (
            " from the sample an earlier run kept" if res.kept else f", {res.solve_ms / 1e3:.1f} s"
        )
        progress(
            f"limits: chamber {curve.name}: volume {volume / curve.rest_volume_mm3:.3f} V0, "
            f"pressure {p:.4g} kPa ({res.iterations} Newton steps{how})"
        )
    return p


def _curve_solver(
    model: FemModel, solver: LinearSolver | None, options: SolverOptions | None
) -> LinearSolver:
    """The linear solver a curve's samples share: `solver`, or the model's of the
    options' kind (PCG without options)."""
    solver = solver or model.make_solver(options.linear_solver if options else "pcg")
    if len(getattr(model, "pinned_dofs", ())) and hasattr(solver, "indefinite"):
        # on the 3-2-1 support the tangents at the Newton iterates of the first sample
        # already had 3 negative eigenvalues (the thick sphere, inflated and sucked in;
        # the default Fruit on its fixed base none): skip the positive definite
        # factorization that fails there (the indefinite type factors either kind)
        solver.indefinite = True
    return solver


def _out_of_range(
    curve: ChamberCurve,
    s: float,
    step: float,
    direction: int,
    stretches: list[float],
    deadline: float | None,
) -> bool:
    """Whether the next sample, at mean stretch `s`, leaves the range followed or comes
    after the deadline; then the curve's end (and collapse pressure) says so."""
    if direction > 0 and s > MAX_STRETCH + 1e-9:
        curve.end = f"the range followed (mean stretch {s - step:.2f})"
        return True
    if direction < 0 and s < MIN_STRETCH - 1e-9:
        # the next sample would leave under COLLAPSE_VOLUME: the walls about to meet
        curve.collapse_pressure_kpa = min(curve.pressure_kpa)
        curve.end = f"the cavity is nearly empty, at {stretches[-1] ** 3:.3f} V0"
        return True
    if deadline is not None and time.monotonic() > deadline:
        curve.end = f"the time budget (mean stretch {stretches[-1]:.2f})"
        return True
    return False


def _sample_options(
    options: SolverOptions, last: float, budget: tuple[float, float]
) -> SolverOptions:
    """A sample's solver options after the first: at most budget[0] times the longest
    sample so far `last` (s) or budget[1] s, at most SAMPLE_SUBDIVISIONS load-step
    halvings, and Newton given up once it stalls (STALL_STEPS)."""
    return replace(
        options,
        max_seconds=max(budget[0] * last, budget[1]),
        max_subdivisions=min(options.max_subdivisions, SAMPLE_SUBDIVISIONS),
        stall_steps=STALL_STEPS,
    )


def _no_equilibrium(curve: ChamberCurve, exc: Exception, s: float, direction: int) -> None:
    """End the curve at the sample at mean stretch `s` that found no equilibrium."""
    why = "no equilibrium"
    if isinstance(exc, OutOfTime):
        why = "no equilibrium found within the time"
    elif isinstance(exc, Stalled):
        why = "no equilibrium (Newton stalled)"
    curve.end = f"{why} at {s**3:.2f} V0"
    curve.failed = True
    if direction < 0:
        curve.collapse_pressure_kpa = min(curve.pressure_kpa)


def _levels_off(
    model: FemModel,
    curve: ChamberCurve,
    stretches: list[float],
    direction: int,
    stop_beyond_kpa: float | None,
    slope_at_rest: float | None = None,
) -> bool:
    """Whether the curve levels off short of the pressure asked: an inflation below it
    (a bound of the limit), a suction above it down to MIN_STRETCH (a bound of the
    collapse; `levels_off_bound`, after the first sample with the slope at rest and
    ``ONE_SAMPLE_MARGIN``); then the bound and the end are the curve's."""
    if stop_beyond_kpa is None:
        return False
    pressure, s = np.array(curve.pressure_kpa), np.array(stretches)
    bound = refusing_bound(model, pressure, s, stop_beyond_kpa, _end(direction), slope_at_rest)
    if bound is None:
        return False
    if direction > 0:
        curve.limit_bound_kpa = bound
        curve.end = f"the pressure levels off below {bound:.3g} kPa"
    else:
        curve.collapse_bound_kpa = bound
        curve.end = f"the suction levels off above {bound:.3g} kPa"
    return True


def _turned(
    model: FemModel,
    curve: ChamberCurve,
    stretches: list[float],
    res: StateResult,
    direction: int,
    fall_steps: int,
) -> bool:
    """Whether the curve turned at its last sample `res`: an inflation `fall_steps`
    samples past its peak (the limit point, `peak`), or a suction collapsing (the
    cavity's volume gone, elements about to invert, or `fall_steps` samples past the
    lowest pressure); then the limit or collapse and the end are the curve's."""
    pr = np.array(curve.pressure_kpa)
    if direction > 0:
        top = int(np.argmax(pr))
        if 0 < top < len(pr) - 1 and len(pr) - 1 - top >= fall_steps:
            s_top, p_top = peak(np.array(stretches), pr, top)
            curve.limit_pressure_kpa = p_top
            curve.limit_growth_mm3 = curve.rest_volume_mm3 * (s_top**3 - 1.0)
            curve.end = "past the limit point"
            return True
        return False
    low = int(np.argmin(pr))
    why = None
    if np.any(res.chamber_volume_mm3 <= COLLAPSE_VOLUME * model.chamber_rest_volume_mm3):
        why = "the cavity's volume is gone"
    elif res.min_det_f <= COLLAPSE_DET_F:
        why = f"elements are about to invert (det F = {res.min_det_f:.2f})"
    elif low < len(pr) - 1 and len(pr) - 1 - low >= fall_steps:
        why = "the wall buckles in (the suction falls off)"
    if why:
        curve.collapse_pressure_kpa = float(pr[low])
        curve.end = why
        return True
    return False


CHECK_TOLERANCE = 1e-3
"""Newton's relative residual on the samples of a curve (`fruit limits`,
`check_pressures`): on the default Fruit's chamber c3 the samples took 34 Newton steps
(18.0 s of CPU) instead of 42 (22.6 s) at 1e-4, with the same pressures to four digits
and the limit within 1e-5."""

STEP_BUDGET = (4.0, 5.0)
"""Time budget of one sample of a curve: this many times the longest sample before it,
and at least this many seconds (a sample that fails, e.g. as the walls buckle in, costs
little more than one that converges; the first sample, from rest, has the scene's
budget). Not the sample just before: on the default Fruit the chambers together took 3 s
for their second sample (4 Newton steps) and 12.4 s for their third."""

CURVE_HALVINGS = 2
"""Times an inflation sample of `fruit limits` that finds no equilibrium is tried again
half as far from the last one: near a flat chamber's peak a step of 0.1 in the mean
stretch can be too long (the default Fruit's chambers together found none at 4.9 V0
after 4.1 V0)."""

STALL_STEPS = 4
"""Newton steps in a row that must cut a sample's residual by `tolerances.STALL_CUT`
(after the curve's first sample). A sample past a collapse can stall instead of
failing: past the default Fruit's chamber c3 it ran on to its time budget (7 s, 12
Newton steps from a relative residual of 2.6e-2 to 2.4e-2). Ending it at the stall
changes no sample that converges, and the curve ends as before, at its last
equilibrium."""

SAMPLE_SUBDIVISIONS = 2
"""Load-step halvings of a sample of a curve after the first (the scene's [solver]
max_subdivisions is for its states): a sample that needs more is past the range
followed (the walls meeting, a step past a peak too long: `CURVE_HALVINGS` then tries a
shorter one). With 6, the default Fruit's chambers c2 and c3 spent 29 s and 18 s of CPU
(47 s and 42 s on a shared machine) on the suction sample that found no equilibrium
within its budget."""


def _start_from_last(solver: LinearSolver) -> None:
    """Have the next inflation sample start from the last one: keep only the last state
    for the predictor and drop the first state's dx/dp (`newton._history_guess`,
    `_sensitivity_guess`). Near a flat chamber's peak the wall turns, and a start
    extrapolated along straight lines dilates its elements: on the default Fruit's c1
    the sample past the peak took 21 Newton steps from the secant over the kept states,
    16 from the last state's own tangent and 10 from the last state; the curve took 34 s
    instead of 85 s. Suction keeps the secant (3 steps a sample on the same chamber, 4-7
    from the last state)."""
    solver.history, solver.sensitivity = solver.history[-1:], None
