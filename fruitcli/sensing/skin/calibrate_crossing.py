"""Calibrating the electrostatic skin (``[skin].model = "electrostatic"``) from a bench
recording: its one calibrated number, the counts per fF, and a gain per taxel.

Units: mm, fF, counts. The model fitted is the one the virtual bench and the printer
emulator replay (`crossing_skin.CrossingSkin`):

    v(frame, taxel) = gain_t * counts_per_ff * D(p - t, gap + p_z - t_z)

D the crossing table's drop -dC (fF) for the recording's indenter, interpolated as the
bench does, p the sample's contact point, t the taxel at rest, gap the tip's height above
p (`calibrate.descent_gaps`). Least squares over log-parameters, the gains normalized to
mean 1 over the measured taxels (their common factor is counts_per_ff); a taxel whose
fitted activation never reaches the calibration's ``MEASURED_MIN_COUNTS`` keeps gain 1.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError

if TYPE_CHECKING:
    from fruitcli.scene import SkinSection
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin

CROSSING_KEYS = ("permittivity", "yarn_radius_mm", "insulation_mm", "gaps_mm")
"""[skin] keys of the crossing's cell, carried into skin.toml so its table is the same."""


def drop_ff(
    response: CrossingSkin,
    indenter: str,
    contact_mm: np.ndarray,
    taxels_mm: np.ndarray,
    gap_mm: np.ndarray,
) -> np.ndarray:
    """The table's drop -dC (fF) (M, T) for contact points (M, 3), taxels (T, 3), gaps (M,)."""
    off = np.asarray(contact_mm, float)[:, None, :] - np.asarray(taxels_mm, float)[None]
    gap = np.asarray(gap_mm, float)[:, None] + off[..., 2]
    counts = response.drop(indenter, off[..., 0], off[..., 1], gap)
    return counts / response.counts_per_ff


def fit_scale(v: np.ndarray, drop: np.ndarray, measured_min: float, gauge: float) -> dict:
    """Fit v (M, T) counts = g_t * s * drop (M, T) fF; a taxel is measured when its fitted
    activation reaches `measured_min` counts; `gauge` weighs mean(log g) = 0. ->
    {counts_per_ff, gain (T,), measured (T,), rms_counts}."""
    from scipy.optimize import least_squares

    t = v.shape[1]
    if not np.any(drop > 0):
        raise FrameError("the crossing's table gives no activation at the recording's frames")

    def model(x: np.ndarray):
        return np.exp(x[0]) * np.exp(x[1:])[None, :] * drop

    def residual(x: np.ndarray):
        return np.concatenate([(model(x) - v).ravel(), [gauge * x[1:].mean()]])

    def jacobian(x: np.ndarray):
        m = model(x)
        jac = np.zeros((m.size + 1, 1 + t))
        jac[:-1, 0] = m.ravel()
        rows = np.arange(m.size)
        jac[rows, 1 + rows % t] = m.ravel()
        jac[-1, 1:] = gauge / t
        return jac

    guess = float(np.sum(v * drop) / max(np.sum(drop * drop), 1e-300))
    x0 = np.r_[np.log(max(guess, 1e-6)), np.zeros(t)]
    res = least_squares(residual, x0, jac=jacobian, method="trf", x_scale="jac")
    pred = model(res.x)
    measured = pred.max(axis=0) >= measured_min
    g = np.where(measured, np.exp(res.x[1:]), np.nan)
    scale = float(np.nanmean(g)) if measured.any() else 1.0
    return {
        "counts_per_ff": float(np.exp(res.x[0]) * scale),
        "gain": np.where(measured, g / scale, 1.0),
        "measured": measured,
        "rms_counts": float(np.sqrt(np.mean((pred - v) ** 2))),
    }


def skin_toml(skin: SkinSection, fit: dict, noise: float, gains_name: str = "gains.csv") -> str:
    """The ``[skin]`` table of an electrostatic calibration; `skin` the scene's [skin]
    (its crossing keys carried over)."""
    lines = [
        "# fruit calibrate: the electrostatic skin's counts per fF fitted to a bench recording",
        "[skin]",
        'model = "electrostatic"',
        f"counts_per_ff = {fit['counts_per_ff']:.6g}",
    ]
    for key in CROSSING_KEYS:
        value = getattr(skin, key)
        if value is None:
            continue
        if key == "gaps_mm":
            lines.append(f"{key} = [{', '.join(repr(float(v)) for v in value)}]")
        else:
            lines.append(f"{key} = {float(value)!r}")
    lines += [
        "gain_spread = 0.0",
        f'taxel_gain = "{gains_name}"',
        f"noise_std_counts = {noise:.4f}",
    ]
    return "\n".join(lines) + "\n"
