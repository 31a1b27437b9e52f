"""Chamber pressures checked against their limits before a state is solved: a pressure
past a chamber's limit pressure (inflation) or collapse (suction) is refused in one line
naming the key, the limit and what to give instead (`check_pressures`, `check_together`),
a Newton failure is explained by the limit it ran into (`explain_failure`), and a volume
growth past what the curves cover is refused (`check_growth`). The curves are
`fruitcli.fem.limits`'. Units: mm, mm^3, kPa.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from fruitcli.errors import SceneError, SolverError
from fruitcli.fem.curve_peak import rest_slope
from fruitcli.fem.curve_start import Chambers, forget, ratio_of, start_state
from fruitcli.fem.curve_workers import CurvePool, curve_jobs, curve_label, run_curves
from fruitcli.fem.fem_model import FemModel, LinearSolver
from fruitcli.fem.limits import (
    CHECK_TOLERANCE,
    CURVE_HALVINGS,
    SAMPLE_SUBDIVISIONS,
    STEP_BUDGET,
    ChamberCurve,
    follow,
)
from fruitcli.fem.linear_response import Start, response
from fruitcli.fem.sample_cache import SampleCache
from fruitcli.fem.solver.options import SolverOptions
from fruitcli.fem.state_load import Load

SCREEN_GROWTH = 1.0
"""Pressures whose linearized volume growth p dV/dp (the rest tangent's compliance) stays
under this fraction of the chamber's rest volume are not checked before solving: at its
limit pressure a neo-Hookean sphere has grown 0.31 V0 by that linear measure when thin,
0.70 V0 when its outer radius is twice the inner, so what passes is far past a limit or
(a stiff chamber) far from one. The default Fruit's breathing (12 kPa) stays under it:
following its chambers would cost every run minutes. A pressure screened out that is
past a limit all the same fails in Newton, and `explain_failure` then names the limit."""

CHECK_BUDGET = (2.0, 2.0)
"""`STEP_BUDGET` of the samples of `check_pressures`: a sample that fails there (the
thick sphere's cavity buckling in at 0.34 V0) is the refusal's evidence, and it is
reached in half the time (the converging samples take 3-4 Newton steps each, the
first, from rest, the longest)."""


def rest_compliance(model: FemModel, solver: LinearSolver) -> np.ndarray:
    """(K, K) dV_i/dp_j (mm^3/kPa) of the chambers at rest, from the solver's tangent
    there (its factor is then the one the first state starts with)."""
    return response(model, solver, model.rest)[1]


def kpa(value: float) -> str:
    """A pressure for a message: one decimal from 10 kPa up, three digits below."""
    return f"{value:.1f}" if abs(value) >= 10 else f"{value:.3g}"


def _check_curve(
    model: FemModel,
    which: Chambers,
    direction: int,
    asked: float,
    solver: LinearSolver | None,
    check: SolverOptions,
    progress: Callable[[str], None] | None,
    found: list | None,
    start: Start | None = None,
    samples: SampleCache | None = None,
    compliance: np.ndarray | None = None,
) -> ChamberCurve:
    """The curve of chamber `which` (or of chambers along ratios `which`) followed as
    far as the pressure `asked` (kPa) under the check's options and budget, on `solver`
    (its analysis forgotten afterwards; None: a fresh one) from `start`
    (`start_state`), its samples taken from and kept in `samples` (saved after the
    curve); with a `found` list, followed on to the limit or collapse and appended to it
    as (direction, curve). With the chambers' `compliance` at rest (`rest_compliance`),
    a pressure far past its bound is refused after its first sample
    (`curve_peak.ONE_SAMPLE_MARGIN`)."""
    slope = None if compliance is None else rest_slope(model, ratio_of(model, which), compliance)
    curve = follow(
        model,
        which,
        direction,
        solver=solver,
        options=check,
        stop_beyond_kpa=asked,
        fall_steps=1,
        budget=CHECK_BUDGET,
        stop_at_asked=found is None,
        beyond=(STEP_BUDGET, CURVE_HALVINGS if direction > 0 else 0),
        progress=progress,
        start=start,
        samples=samples,
        slope_at_rest=slope,
    )
    if solver is not None:
        forget(solver)
    if samples is not None:
        samples.save()
    if found is not None:
        found.append((direction, curve))
    return curve


def _curve_to_the_limit(args: tuple) -> ChamberCurve:
    """(model, which, direction, asked, check, start) -> `_check_curve` on a fresh
    solver, followed on to the limit or collapse; module level, for a worker process."""
    model, which, direction, asked, check, start = args
    return _check_curve(model, which, direction, asked, None, check, None, [], start)


def pressure_keys(names: list[str]) -> list[str]:
    """The scene keys of the chambers' pressures ([actuation].pressure_kpa.<name>), as
    `check_pressures` names them in its refusals."""
    return [f"[actuation].pressure_kpa.{name}" for name in names]


def check_pressures(
    model: FemModel,
    pressures: np.ndarray,
    keys: list[str],
    solver: LinearSolver,
    options: SolverOptions,
    progress: Callable[[str], None] | None = None,
    screen: float = SCREEN_GROWTH,
    found: list | None = None,
    kept: Path | None = None,
    pool: CurvePool | None = None,
) -> None:
    """Refuse, with one SceneError line naming keys[k], a chamber pressure past that
    chamber's limit pressure (inflation) or collapse pressure (suction). pressures (S,
    K) kPa, NaN where a chamber is volume controlled. Each chamber is followed by volume
    control (`follow`, the others at rest) only as far as its largest or smallest
    pressure, and only when that pressure's linearized growth passes SCREEN_GROWTH; on
    `solver` (the states' own: its analysis is kept, see `forget`). With a `found`
    list, the curves followed go on to the limit or collapse (unless a bound refuses
    first), all from the body's equilibrium under its weight (`start_state`), and are
    appended to it as (direction, curve). With `kept` (a file), the curves' samples
    solved by an earlier check of the same body are taken from there, and the new ones
    kept there (`SampleCache`). With a `pool`, the curves of a `found` list without
    `kept` are followed over its worker processes (`curve_workers`), refused in the same
    order."""
    if not np.any(np.nan_to_num(pressures)):
        return
    compliance = rest_compliance(model, solver)
    w = np.diag(compliance)
    check = replace(
        options,
        tolerance=max(options.tolerance, CHECK_TOLERANCE),
        load_steps=1,
        max_subdivisions=min(options.max_subdivisions, SAMPLE_SUBDIVISIONS),
    )
    v0 = model.chamber_rest_volume_mm3
    plan = [
        (k, direction, asked)
        for k in range(len(keys))
        for col in [pressures[:, k][np.isfinite(pressures[:, k])]]
        for direction, asked in ((1, col.max(initial=0.0)), (-1, col.min(initial=0.0)))
        if direction * asked > 0 and abs(asked) * w[k] >= screen * v0[k]
    ]
    together = _together_case(model, pressures, compliance, screen)
    if found is not None and kept is None:
        n, why = curve_jobs(pool, len(plan) + (together is not None), 3 * model.n_nodes)
        if pool is not None and n > 1:
            _check_in_workers(
                model, pressures, plan, together, keys, solver, check, progress, found, pool, n, why
            )
            return
    start: list = []  # the curves' `Start`, once one is followed on to its limit
    samples = None if kept is None else SampleCache(model, kept, check)

    def first():
        if found is None:  # mostly one curve, a few samples: each from rest
            return None
        start[:] = start or [start_state(model, solver, check, progress)]
        return start[0]

    for k, direction, asked in plan:
        curve = _check_curve(
            model, k, direction, asked, solver, check, progress, found, first(), samples, compliance
        )
        _refuse(keys[k], asked, direction, curve)
    if together is not None:
        i, ratio, asked = together
        curve = _check_curve(
            model, ratio, 1, asked, solver, check, progress, found, first(), samples, compliance
        )
        _refuse_together(pressures, keys, i, asked, curve)


def _check_in_workers(
    model: FemModel,
    pressures: np.ndarray,
    plan: list[tuple[int, int, float]],
    together: tuple[int, np.ndarray, float] | None,
    keys: list[str],
    solver: LinearSolver,
    check: SolverOptions,
    progress: Callable[[str], None] | None,
    found: list,
    pool: CurvePool,
    workers: int,
    why: str,
) -> None:
    """`check_pressures` with `found`, its curves (`plan`: (chamber, direction, asked),
    and `together`) followed on to their limits in `workers` of `pool`'s processes from the body
    under its weight; the curves appended to `found` and refused in the order of one
    process (the chambers together last)."""
    start = start_state(model, solver, check, progress)
    cases: list[tuple] = [(model, k, d, asked, check, start) for k, d, asked in plan]
    if together is not None:
        cases.append((model, together[1], 1, together[2], check, start))
    labels = [curve_label(model.chamber_names, c[1], c[2]) for c in cases]
    order = list(range(len(cases)))
    if together is not None:  # the longest: first
        order = order[-1:] + order[:-1]
    say = progress or (lambda msg: None)
    curves = run_curves(pool, _curve_to_the_limit, cases, labels, order, workers, why, say)
    found += [(d, curve) for (k, d, asked), curve in zip(plan, curves, strict=False)]
    if together is not None:
        found.append((1, curves[-1]))
    for (k, d, asked), curve in zip(plan, curves, strict=False):
        _refuse(keys[k], asked, d, curve)
    if together is not None:
        _refuse_together(pressures, keys, together[0], together[2], curves[-1])


def _refuse(key: str, asked: float, direction: int, curve: ChamberCurve) -> None:
    """SceneError naming `key` when the pressure `asked` (kPa) lies past what chamber
    `curve` (followed in `direction`: 1 inflation, -1 suction) reaches: its limit or
    collapse, a bound of either, or where no equilibrium was found; nothing when it is
    reached."""
    if direction > 0 and curve.limit_pressure_kpa is not None and asked < curve.limit_pressure_kpa:
        return
    if (
        direction < 0
        and curve.collapse_pressure_kpa is not None
        and asked > curve.collapse_pressure_kpa
    ):
        return
    if direction > 0 and curve.limit_bound_kpa is not None:
        raise SceneError(
            f"{key}: {asked:g} kPa is past this chamber's limit pressure, which is "
            f"at most {kpa(curve.limit_bound_kpa)} kPa (a bound: its pressure-volume "
            "curve levels off, and there is no equilibrium above its peak; `fruit "
            "limits` computes the limit); give `volume_growth_mm3` to follow the "
            "inflation past it"
        )
    if direction > 0 and curve.limit_pressure_kpa is not None:
        raise SceneError(
            f"{key}: {asked:g} kPa is past this chamber's limit pressure of "
            f"{kpa(curve.limit_pressure_kpa)} kPa (no equilibrium above it); give "
            "`volume_growth_mm3` to follow the inflation past it"
        )
    if direction > 0 and curve.failed and len(curve.pressure_kpa) == 1:
        raise SceneError(
            f"{key}: {asked:g} kPa was not reached: following this chamber's "
            "inflation by volume control found no equilibrium at its first sample "
            f"({curve.end}): the body may not hold under its other loads (its "
            "weight, jigs); check them, or lower the pressure"
        )
    if direction > 0 and curve.failed and max(curve.pressure_kpa) < asked:
        raise SceneError(
            f"{key}: {asked:g} kPa was not reached: following this chamber's "
            "inflation by volume control found no equilibrium beyond "
            f"{kpa(max(curve.pressure_kpa))} kPa ({curve.end}; past a limit point, "
            "or the body does not hold under its other loads); lower it or give "
            "`volume_growth_mm3`"
        )
    if direction < 0 and curve.collapse_bound_kpa is not None:
        raise SceneError(
            f"{key}: {asked:g} kPa is past this chamber's collapse, whose pressure is at "
            f"least {kpa(curve.collapse_bound_kpa)} kPa (a bound: its pressure-volume "
            "curve levels off before its walls would meet, and self-contact is not "
            "modelled; `fruit limits` computes the collapse); give `volume_growth_mm3` "
            "to follow the suction"
        )
    if direction < 0 and curve.failed:
        raise SceneError(
            f"{key}: {asked:g} kPa is past this chamber's collapse: no equilibrium "
            f"was found beyond {kpa(min(curve.pressure_kpa))} kPa ({curve.end}: "
            "its walls buckle in or meet, and self-contact is not modelled); give "
            "`volume_growth_mm3` to follow the suction"
        )
    if direction < 0 and curve.collapse_pressure_kpa is not None:
        raise SceneError(
            f"{key}: {asked:g} kPa is past this chamber's collapse pressure of "
            f"{kpa(curve.collapse_pressure_kpa)} kPa ({curve.end}: its walls would "
            "meet, and self-contact is not modelled); give `volume_growth_mm3` to "
            "follow the suction"
        )


def check_together(
    model: FemModel,
    pressures: np.ndarray,
    keys: list[str],
    solver: LinearSolver,
    check: SolverOptions,
    compliance: np.ndarray,
    screen: float,
    progress: Callable[[str], None] | None = None,
) -> None:
    """Refuse, in one line naming the state's keys, the state whose pressures, several
    chambers inflated together, are past the chambers' limit along their own ratios
    (`_together_case`), followed along its ratios (`follow` with ratios) as far as the
    largest chamber pressure, from rest."""
    case = _together_case(model, pressures, compliance, screen)
    if case is not None:
        i, ratio, asked = case
        curve = _check_curve(model, ratio, 1, asked, solver, check, progress, None)
        _refuse_together(pressures, keys, i, asked, curve)


def _together_case(
    model: FemModel, pressures: np.ndarray, compliance: np.ndarray, screen: float
) -> tuple[int, np.ndarray, float] | None:
    """(state, ratios (K,), largest pressure kPa) of the state `check_together` follows:
    the one with the largest chamber pressure among those with several chambers inflated
    (all pressure controlled), when its linearized growth of sum_k r_k V_k passes
    `screen` of the rest; None otherwise."""
    rows = np.nan_to_num(pressures, nan=-1.0)
    several = np.flatnonzero(((rows > 0).sum(1) >= 2) & (rows >= 0).all(1))
    if not len(several):
        return None
    i = int(several[np.argmax(rows[several].max(1))])
    asked = float(rows[i].max())
    ratio = rows[i] / asked
    v0 = model.chamber_rest_volume_mm3
    if asked * float(ratio @ compliance @ ratio) < screen * float(ratio @ v0):
        return None
    return i, ratio, asked


def _refuse_together(
    pressures: np.ndarray, keys: list[str], i: int, asked: float, curve: ChamberCurve
) -> None:
    """SceneError naming state i's keys when its largest pressure `asked` (kPa) is past
    the limit (or a bound of it) of the chambers' `curve` along its ratios."""
    if curve.limit_pressure_kpa is not None and asked < curve.limit_pressure_kpa:
        return
    rows = np.nan_to_num(pressures, nan=-1.0)
    which = ", ".join(f"{keys[k]} {rows[i, k]:g} kPa" for k in np.flatnonzero(rows[i] > 0))
    if curve.limit_bound_kpa is not None:
        limit = f"at most {kpa(curve.limit_bound_kpa)} kPa (a bound: the curve levels off)"
    elif curve.limit_pressure_kpa is not None:
        limit = f"{kpa(curve.limit_pressure_kpa)} kPa"
    else:
        return
    raise SceneError(
        f"state {i}: {which}: together these are past the chambers' limit along these "
        f"ratios, where the largest chamber pressure is {limit}; no equilibrium above "
        "it; lower them or give `volume_growth_mm3`"
    )


def explain_failure(
    model: FemModel,
    load: Load,
    keys: list[str],
    solver: LinearSolver,
    options: SolverOptions,
    error: SolverError,
    progress: Callable[[str], None] | None = None,
) -> None:
    """After `error` (a state under `load` found no equilibrium): raise the one line of
    `check_pressures` when a chamber's pressure in `load` is past its limit or collapse
    (followed without the screen), else `error` itself."""
    vc = np.asarray(load.volume_controlled, bool)
    asked = np.where(vc, np.nan, load.pressure_kpa)[None, :]
    if np.any(np.nan_to_num(asked)):
        forget(solver)
        check_pressures(model, asked, keys, solver, options, progress, screen=0.0)
    raise error


def check_growth(model: FemModel, loads: list[Load]) -> None:
    """Refuse, with one SceneError line, a volume growth that would take a chamber to no
    volume or less (growth <= -V0)."""
    v0 = model.chamber_rest_volume_mm3
    for load in loads:
        vc = np.asarray(load.volume_controlled, bool)
        for k in np.flatnonzero(vc & (np.asarray(load.volume_growth_mm3) <= -v0)):
            name = model.chamber_names[k]
            raise SceneError(
                f"[actuation].volume_growth_mm3.{name}: "
                f"{load.volume_growth_mm3[k]:g} mm^3 would leave the chamber no "
                f"volume (its rest volume is {v0[k]:.4g} mm^3): expected more "
                f"than {-v0[k]:.4g}"
            )


LIMITS_FILE = "limits.json"
"""The limits stage's summary (`fruitcli.fem.limits_stage.run_limits_stage`)."""


def checked_by(limits_dir: str | Path | None) -> bool:
    """True when the limits stage's output is in `limits_dir` (simulate then skips its
    own check: the stage checked the same pressures on the same mesh)."""
    return limits_dir is not None and (Path(limits_dir) / LIMITS_FILE).exists()
