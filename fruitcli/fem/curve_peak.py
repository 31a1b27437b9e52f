"""What the samples of a chamber's pressure-volume curve (pressure against the mean
stretch s = (V / V0)^(1/3)) say about its peak, for `fruitcli.fem.limits`: the vertex of
the parabola through three samples (`peak`, `vertex`: the limit pressure), and a bound
of the limit (inflation) or of the collapse (suction) while a neo-Hookean curve levels
off (`levels_off_bound`, after one sample with the slope at rest `rest_slope`), which
refuses a pressure asked past it (`refusing_bound`). Units: kPa, mm^3.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from fruitcli.fem.fem_model import FemModel

MAX_STRETCH = 3.0
"""Inflation is followed up to this mean stretch (27 V0); a chamber whose pressure still
rises there has no limit in the range (limit null)."""


def peak(stretch: np.ndarray, pressure: np.ndarray, i: int) -> tuple[float, float]:
    """(stretch, pressure) at the vertex of the parabola through samples i - 1, i, i + 1
    (sample i the largest); sample i itself when the parabola opens upward."""
    s, p = stretch[i - 1 : i + 2], pressure[i - 1 : i + 2]
    a, b, c = np.polyfit(s, p, 2)
    if a >= 0:
        return float(stretch[i]), float(pressure[i])
    s_top = float(np.clip(-b / (2 * a), s[0], s[-1]))
    return s_top, float(np.polyval([a, b, c], s_top))


def levels_off_bound(
    model: FemModel,
    pressure: np.ndarray,
    stretch: np.ndarray,
    slope_at_rest: float | None = None,
    end: float = MAX_STRETCH,
) -> float | None:
    """A bound (kPa) of the pressures a neo-Hookean chamber's curve reaches from its last
    sample on to the mean stretch `end`, from its samples so far (pressures at mean
    stretches `stretch`, the first the rest's): once its slopes dp/ds shrink, the secant
    of the last step overestimates the slope from there on, and the curve stays on the
    near side of the secant continued to `end`. Inflation (`end` MAX_STRETCH, above the
    samples): an upper bound of the pressure, the curve concave in the stretch as before
    a neo-Hookean chamber's limit point. Suction (`end` below the samples, the walls
    about to meet): a lower bound, the suction levelling off as a flat chamber's walls
    bend in (a spherical cavity's steepens: no bound). With one sample past rest, the
    slope at rest `slope_at_rest` (kPa per unit of stretch, `rest_slope`) is the first of
    the slopes compared. None with fewer samples, slopes that do not shrink, or another
    material (Yeoh's stiffening can bend the curve up again)."""
    if model.material_name != "neo-hookean" or len(pressure) < 2:
        return None
    g2 = (pressure[-1] - pressure[-2]) / (stretch[-1] - stretch[-2])
    if len(pressure) >= 3:
        g1 = (pressure[-2] - pressure[-3]) / (stretch[-2] - stretch[-3])
    elif slope_at_rest is not None:
        g1 = slope_at_rest
    else:
        return None
    if not 0 < g2 < g1:
        return None
    return float(pressure[-1] + g2 * (end - stretch[-1]))


def rest_slope(model: FemModel, r: np.ndarray, compliance: np.ndarray) -> float:
    """dp/ds (kPa) at rest of the curve of chambers along ratios r (K,) (a chamber alone:
    its unit vector), s the mean stretch (V / V0)^(1/3), from the chambers' compliance
    dV/dp (K, K) mm^3/kPa at rest (`pressure_check.rest_compliance`)."""
    return float(3.0 * (r @ model.chamber_rest_volume_mm3) / (r @ compliance @ r))


def refusing_bound(
    model: FemModel,
    pressure: np.ndarray,
    stretch: np.ndarray,
    asked: float,
    end: float,
    slope_at_rest: float | None = None,
) -> float | None:
    """The bound `levels_off_bound` (kPa) of a curve's samples so far when it refuses the
    pressure `asked` (kPa): `asked` past it towards `end` (above it for an inflation,
    `end` above the samples; below it for a suction), or past ONE_SAMPLE_MARGIN times it
    after the first sample alone; None otherwise."""
    bound = levels_off_bound(model, pressure, stretch, slope_at_rest, end)
    margin = ONE_SAMPLE_MARGIN if len(pressure) == 2 else 1.0
    direction = 1.0 if end > stretch[-1] else -1.0
    if bound is None or direction * (asked - margin * bound) <= 0:
        return None
    return bound


ONE_SAMPLE_MARGIN = 2.0
"""A curve is ended by `levels_off_bound` after its first sample (the slope at rest the
first of the slopes compared) only for a pressure asked past this many times that bound
(above it for an inflation, below it for a suction): the curve's rest point is taken at
pressure 0, which under the body's weight holds only to the pressure the weight puts on
the chamber (on the default Fruit a hundredth of the first sample's). After two samples
the bound stands on solved samples alone, and the pressure asked need only be past it."""


PEAK_AHEAD = 0.5
"""An inflation curve (neo-Hookean) ends without a sample past its peak once the
parabola through its last three samples has its vertex less than this many steps ahead
of the last sample, rising less than PEAK_RISE above it: the vertex is then the limit.
On the default Fruit the sample past each chamber's peak was the slowest of its curve
(7-10 Newton steps against 3-5), and the vertex ahead is the limit of the parabola
through the top and its neighbours within 0.05 %."""

PEAK_RISE = 1e-3
"""Largest rise of the vertex ahead above the last sample (relative) that `PEAK_AHEAD`
takes as the limit: the extrapolation's error is a fraction of it."""


def vertex(stretch: np.ndarray, pressure: np.ndarray) -> tuple[float, float] | None:
    """(stretch, pressure) of the vertex of the parabola through the last three samples
    when it opens downward, else None."""
    if len(pressure) < 3:
        return None
    a, b, c = np.polyfit(stretch[-3:], pressure[-3:], 2)
    if not a < 0:
        return None
    top = -b / (2 * a)
    return float(top), float(np.polyval([a, b, c], top))
