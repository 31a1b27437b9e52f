"""Limit pressures of a body's chambers: each chamber's pressure-volume curve followed
under volume control (the chamber's volume is the load, its pressure the unknown Lagrange
multiplier, as `[actuation].volume_growth_mm3` does), one chamber at a time with the
others at rest (pressure 0).

- Inflation: the pressure rises, peaks at the limit pressure (the largest pressure the
  chamber holds: pressure control has no equilibrium above it) and falls; the curve is
  followed until it has fallen for FALL_STEPS steps, and the peak is the vertex of the
  parabola through the largest sample and its neighbours.
- Suction: the pressure falls (below 0) while the cavity shrinks, until its walls would
  meet (self-contact is not modelled): the volume under COLLAPSE_VOLUME of its rest
  volume, an element at the wall about to invert (det F under COLLAPSE_DET_F), the
  pressure turning back towards 0 (the wall buckling in) or no equilibrium; the
  collapse pressure is the lowest pressure reached.

Steps are uniform in the chamber's mean stretch s = (V / V0)^(1/3) (the inner stretch
of a spherical cavity). Units: mm, mm^3, kPa.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from fruitcli.errors import SolverError
from fruitcli.fem.model import Load
from fruitcli.fem.solver.newton import SolverOptions, solve_state

STRETCH_STEP = 0.1
"""Step of the mean stretch (V / V0)^(1/3) between samples of a curve: the thick
sphere's peak (at stretch 1.83) comes out of the parabola within 0.1 % of the densely
sampled curve's."""

MAX_STRETCH = 3.0
"""Inflation is followed up to this mean stretch (27 V0); a chamber whose pressure still
rises there has no limit in the range (limit null)."""

FALL_STEPS = 2
"""Samples below the largest pressure that end an inflation curve (past its peak)."""

MIN_STRETCH = 0.3
"""Suction is followed down to this mean stretch (2.7 % of the rest volume)."""

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


def chamber_load(model, k: int, growth_mm3: float) -> Load:
    """Chamber k held at rest volume + growth_mm3, the other chambers at pressure 0;
    gravity and jigs as in the scene's states (full)."""
    n = len(model.chamber_tris)
    growth = np.zeros(n)
    growth[k] = growth_mm3
    vc = np.zeros(n, bool)
    vc[k] = True
    return Load(np.zeros(n), growth, vc, 1.0, 1.0)


def peak(stretch: np.ndarray, pressure: np.ndarray, i: int) -> tuple[float, float]:
    """(stretch, pressure) at the vertex of the parabola through samples i - 1, i, i + 1
    (sample i the largest); sample i itself when the parabola opens upward."""
    s, p = stretch[i - 1:i + 2], pressure[i - 1:i + 2]
    a, b, c = np.polyfit(s, p, 2)
    if a >= 0:
        return float(stretch[i]), float(pressure[i])
    s_top = float(np.clip(-b / (2 * a), s[0], s[-1]))
    return s_top, float(np.polyval([a, b, c], s_top))


def follow(model, k: int, direction: int = 1, *, solver=None,
           options: SolverOptions | None = None, stop_beyond_kpa: float | None = None,
           step: float = STRETCH_STEP, deadline: float | None = None,
           progress=None) -> ChamberCurve:
    """Chamber k's curve from rest: inflation (direction 1) up to MAX_STRETCH or past
    the limit, suction (direction -1) down to MIN_STRETCH or the collapse. With
    `stop_beyond_kpa`, it stops as soon as the pressure passes that value (reachable:
    neither a limit nor a collapse before it). `deadline` (time.monotonic()) ends the
    curve where it is. `progress(msg)` is told each sample."""
    name = model.chamber_names[k]
    v0 = float(model.chamber_rest_volume_mm3[k])
    curve = ChamberCurve(name, v0, [0.0], [0.0])
    solver = solver or model.make_solver(options.linear_solver if options else "pcg")
    options = options or SolverOptions(load_steps=1)
    stretches = [1.0]
    x, prev, p_start = None, None, None
    s = 1.0
    while True:
        s = s + direction * step
        if (direction > 0 and s > MAX_STRETCH + 1e-9) or (direction < 0 and s < MIN_STRETCH - 1e-9):
            curve.end = f"the range followed (mean stretch {s - direction * step:.2f})"
            break
        if deadline is not None and time.monotonic() > deadline:
            curve.end = f"the time budget (mean stretch {stretches[-1]:.2f})"
            break
        load = chamber_load(model, k, v0 * (s**3 - 1.0))
        try:
            res = solve_state(model, load, x_start=x, load_start=prev, pressure_start=p_start,
                              options=options, solver=solver, label=f"chamber {name}")
        except SolverError as exc:
            curve.end = f"no equilibrium at mean stretch {s:.2f} ({exc})"
            if direction < 0:
                curve.collapse_pressure_kpa = min(curve.pressure_kpa)
            break
        x, prev, p_start = res.x, load, res.pressure_kpa
        p = float(res.pressure_kpa[k])
        stretches.append(s)
        curve.growth_mm3.append(float(res.chamber_volume_mm3[k] - v0))
        curve.pressure_kpa.append(p)
        if progress:
            progress(f"limits: chamber {name}: volume {res.chamber_volume_mm3[k] / v0:.3f} V0, "
                     f"pressure {p:.4g} kPa ({res.solve_ms / 1e3:.1f} s)")
        if stop_beyond_kpa is not None and direction * (p - stop_beyond_kpa) >= 0:
            curve.end = f"the pressure asked ({stop_beyond_kpa:g} kPa)"
            break
        pr = np.array(curve.pressure_kpa)
        if direction > 0:
            top = int(np.argmax(pr))
            if 0 < top < len(pr) - 1 and len(pr) - 1 - top >= FALL_STEPS:
                s_top, p_top = peak(np.array(stretches), pr, top)
                curve.limit_pressure_kpa = p_top
                curve.limit_growth_mm3 = v0 * (s_top**3 - 1.0)
                curve.end = "past the limit point"
                break
        else:
            low = int(np.argmin(pr))
            why = None
            if res.chamber_volume_mm3[k] <= COLLAPSE_VOLUME * v0:
                why = "the cavity's volume is gone"
            elif res.min_det_f <= COLLAPSE_DET_F:
                why = f"elements are about to invert (det F = {res.min_det_f:.2f})"
            elif low < len(pr) - 1 and len(pr) - 1 - low >= FALL_STEPS:
                why = "the wall buckles in (the suction falls off)"
            if why:
                curve.collapse_pressure_kpa = float(pr[low])
                curve.end = why
                break
    return curve
