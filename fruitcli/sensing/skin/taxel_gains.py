"""Per-taxel gains measured where the skin's law does not matter: from bench samples
right over a taxel.

Units: mm, counts. A sample half a pitch off its taxels sees each of them through the
footprint's flank, so the gains a calibration fits there take up whatever the fitted law
gets wrong at that distance (a Gaussian fitted to a board whose footprint has heavier
tails, a computed crossing table fitted to a real board). Right over a taxel the
footprint is at its top for any law: taxel t reads g_t * a(gap), with a(gap) the same
for every taxel at the same gap. So the activations of the taxels, each over its own
descent, compared at the same gaps, give the gains' ratios without the law:

    g_t ~ sum_k a_t(h_k) * (a_t(h_k) / mean_u a_u(h_k)) / sum_k a_t(h_k)

over ``COMMON_GAPS`` gaps h_k spread over the range every such descent covers, each
taxel's activation linear between its frames' gaps, the gaps where the taxels' mean
activation is under ``MIN_MEAN_COUNTS`` left out.
"""

from __future__ import annotations

import numpy as np

OVER_TAXEL_MM = 0.5
"""A sample whose contact point lies this close to a taxel, seen from above, is over it
(a printer places its samples to 0.1 mm)."""

COMMON_GAPS = 24
"""Gaps at which the descents over the taxels are compared."""

MIN_MEAN_COUNTS = 5.0
"""A gap is used when the taxels' mean activation there reaches this (counts): a few
times the noise of Fig. 10."""


def gains_over_taxels(
    v: np.ndarray, contact_mm: np.ndarray, gaps_mm: np.ndarray, taxels_mm: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(gain (T,), over (T,) bool) from the descent frames' activations v (M, T) counts
    over the baseline, their samples' contact points (M, 3) mm and the tip's gaps (M,) mm,
    for taxels (T, 3) mm: the gains of the taxels with a sample over them (mean 1 over
    those; NaN for the others), and which they are. Fewer than two such taxels, or
    descents that share no gap with enough activation: none is over."""
    t = len(taxels_mm)
    gain = np.full(t, np.nan)
    over = np.zeros(t, bool)
    if len(v) == 0:
        return gain, over
    d = np.hypot(
        contact_mm[:, None, 0] - taxels_mm[None, :, 0],
        contact_mm[:, None, 1] - taxels_mm[None, :, 1],
    )  # (M, T)
    nearest = np.argmin(d, axis=1)
    frames_over = d[np.arange(len(v)), nearest] <= OVER_TAXEL_MM
    descents = {k: np.flatnonzero(frames_over & (nearest == k)) for k in range(t)}
    descents = {k: f for k, f in descents.items() if len(f) >= 2}
    if len(descents) < 2:
        return gain, over
    low = max(float(gaps_mm[f].min()) for f in descents.values())
    high = min(float(gaps_mm[f].max()) for f in descents.values())
    if not high > low:
        return gain, over
    grid = np.linspace(low, high, COMMON_GAPS)
    taxels = np.array(sorted(descents))
    table = np.empty((len(taxels), COMMON_GAPS))
    for row, k in enumerate(taxels):
        f = descents[k]
        order = np.argsort(gaps_mm[f])
        table[row] = np.interp(grid, gaps_mm[f][order], v[f[order], k])
    mean = table.mean(axis=0)
    used = mean >= MIN_MEAN_COUNTS
    if not used.any():
        return gain, over
    ratio = table[:, used] / mean[used]
    weight = np.maximum(table[:, used], 0.0)
    g = np.sum(weight * ratio, axis=1) / np.maximum(np.sum(weight, axis=1), 1e-300)
    gain[taxels] = g / g.mean()
    over[taxels] = True
    return gain, over


def combine(
    fitted: np.ndarray, measured: np.ndarray, gain: np.ndarray, over: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """Each taxel's gain (T,): the one over it where there is one, scaled to the fitted
    gains' mean over the taxels that have both; else the fitted one. -> (gains, measured
    (T,), factor): the gains normalized to mean 1 over the measured taxels, and the factor
    they were divided by (the law's amplitude takes it)."""
    both = over & measured
    scale = float(np.mean(fitted[both]) / np.mean(gain[both])) if both.any() else 1.0
    out = np.where(over, gain * scale, fitted)
    measured = measured | over
    factor = float(np.mean(out[measured])) if measured.any() else 1.0
    return np.where(measured, out / factor, 1.0), measured, factor
