"""Touches placed by the skin's model (``[detection].method = "model"``).

Units: mm, counts, grid units (taxel pitches).

The paper's N9 centroid pulls every touch towards the nearest crossing: a weighted mean
of three taxels per axis cannot reach past them, and the footprint's shape is ignored.
Here each touch the paper's multitouch finds (`detect.n9_sequential`) is refined by a
least-squares fit of the skin's footprint to the taxels around its peak (its N9 and the
ring beyond, a 5 x 5 window of the grid), each taxel where the frame's state puts it:

- the contact point runs over the surface the window's taxels span: a quadratic map of
  the grid coordinates fitted to the taxels' 3D positions (the N9 weighted twice the
  ring) plus the bilinear interpolation of its misfit at the taxels, so c(a, b) passes
  through every taxel and follows the deformed body as they do; where the body's surface
  is known and the recording stays at one state (`Locator.use_surface`), the point runs
  over the body itself instead (`surface_chart`), so a touch past the last taxels can
  follow the body down its flank;
- taxel k reads A g_k f(|c - P_k| / s): f the skin's radial footprint (the Gaussian
  law's or the crossing table's, `FootprintLaw.of`) at its calibrated width, A the
  amplitude, s the width's scale (a wider object, a farther gap), g_k the taxel's gain;
  with the skin's height form (``[skin].height_as_distance``, ``height_as_gap``, which
  `fruit calibrate` fits) the taxel's height difference from c along z enters the
  distance with its weight and the gap with its share instead, and with the skin's
  widening (``[skin].widening_per_mm``) that share of the gap widens the footprint at
  that taxel (`model_kernel`);
- s has a prior: 1 with a 1-sigma of ``WIDTH_PRIOR`` (an assumption: the calibrated
  width is right to about that, the small and the medium indenter differ by 17 %);
  without it a touch at the grid's edge trades width against distance off the edge;
- each residual is weighted by the taxel's noise (its std in the recording's baseline
  frames, `Locator.baseline`; else the skin's one value), with ``MODEL_ERROR`` of its
  activation added in quadrature (an assumption: no calibrated footprint is exact to
  better than about a tenth, so the peak taxel does not outweigh its neighbours);
- the fit starts at the N9 point, amplitude the peak, width scale 1, and is bounded:
  a, b within ``MAX_SHIFT`` pitches of the peak, s in ``WIDTH_BOUNDS``, A in
  ``AMPLITUDE_BOUNDS`` times the peak.

Taxels in another touch's N9 of the same frame are left out of a touch's fit. A touch
keeps N9's position (``fit`` = ``FIT_N9``) when its fit fails a test: a result that is
not finite; a point more than one pitch from N9's (from its peak taxel for a touch that
took its second explanation, below) or on a bound; a width scale more
than ``MAX_WIDTH_SIGMAS`` priors from 1 (a spike, a stuck taxel: not the skin's
footprint); fewer than ``MIN_TAXELS`` taxels in its window; a 1-sigma radius above
``MAX_UNCERTAINTY_MM`` (the taxels do not place it: a weak touch off the grid's edge);
or a reduced chi^2 above
``MAX_REDUCED_CHI2`` (the footprint does not explain the frame: a palm, two merged
fingers, water). The position's 1-sigma radius (mm) is sqrt(trace) of the fit's
covariance mapped to 3D, scaled by the reduced chi^2 when that exceeds 1, and, for a
touch seen from one side only, widened by a second explanation of its frame on the
other side of its peak taxel (`_mirror_spread`), whose point the touch takes where it
explains the frame clearly better (chi^2 lower by ``MIRROR_KEEP``); the residual is the RMS
of the weighted residuals (1: at the noise).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError

if TYPE_CHECKING:
    from fruitcli.sensing.detection.surface_chart import SurfaceChart
    from fruitcli.sensing.skin.heights import HeightModel

HALF = 2  # window half-width (cells): the N9 and the ring beyond it
MODEL_ERROR = 0.1  # share of a taxel's activation added to its noise (assumption)
MAX_SHIFT = 1.5  # pitches from the peak taxel a fitted point may go
WIDTH_BOUNDS = (0.5, 2.0)  # width scale s
WIDTH_PRIOR = 0.15  # 1-sigma of the width scale's prior around 1 (assumption)
MAX_WIDTH_SIGMAS = 2.5  # a width scale farther from 1 (in WIDTH_PRIOR): not the skin's
AMPLITUDE_BOUNDS = (0.3, 10.0)  # amplitude A / peak
ITERATIONS = 12  # Levenberg-Marquardt steps at most
MAX_REDUCED_CHI2 = 9.0  # above: the footprint does not explain the frame
MAX_UNCERTAINTY_MM = 30.0  # a 1-sigma radius above two pitches: the taxels do not place it
MIN_TAXELS = 5  # taxels in the window at least (4 parameters, one to spare)
MIRROR_FAR = 1.0  # grid units out on an open side: where a touch's second fit starts ...
MIRROR_NEAR = 0.25  # ... when its first ended nearer the peak taxel than this
MIRROR_UNSEEN = 3.0  # errors: taxels one row inwards reading less do not see the touch
MIRROR_MIN_MM = 1.0  # a second fit ending nearer the touch's point is the same one
MIRROR_KEEP = 2.0  # chi^2 lower by more: the second fit's point is kept (weight > 0.73)
MIRROR_MISFIT = 1.0  # reduced chi^2 over which a gap-form skin's edge touch is fitted again
RING_WEIGHT = 0.5  # weight of the ring's taxels in the surface map
# an earlier frame shows the same touch when its window's activations point the same way
# (cosine, an assumption: a still touch 20 counts strong over noise of 1-2 counts gives
# 0.9 and more; the same touch one pitch away, about 0.2)
SAME_TOUCH_COSINE = 0.8
PROFILE_STEP_MM = 0.05
FIT_NONE, FIT_MODEL, FIT_N9 = 0, 1, 2  # TouchTable.fit: not fitted, model, N9 kept
FIT_NAMES = ("", "model", "n9")


@dataclass(frozen=True)
class FootprintLaw:
    """The skin's radial footprint f(d) (f(0) = 1) sampled every ``PROFILE_STEP_MM``,
    its nominal width (mm), the noise (counts std), the taxels' gains (T,) or None, the
    1-sigma of a touch's width scale around 1 (``WIDTH_PRIOR``), and how a taxel's height
    difference h from the contact point enters (`model_kernel`): d^2 = r^2 +
    ``height_distance`` h^2, a factor exp(-``height_gap_per_mm`` |h|) and the width
    sigma (s + ``height_widening_per_mm`` |h|), s the touch's width scale (the skin's
    ``[skin].height_as_distance``, ``height_as_gap / gap_decay_mm`` and ``widening_per_mm
    * height_as_gap``: the skin's footprint widens with the gap, and the height's share
    of it; the gap of the touch itself, common to its taxels, is in s)."""

    profile: np.ndarray
    sigma_mm: float
    noise_std_counts: float
    gain: np.ndarray | None = None
    width_prior: float = WIDTH_PRIOR
    height_distance: float = 1.0
    height_gap_per_mm: float = 0.0
    height_widening_per_mm: float = 0.0

    @property
    def height(self) -> np.ndarray:
        """(alpha, kappa per mm, omega per mm) for `model_kernel`."""
        return np.array([self.height_distance, self.height_gap_per_mm, self.height_widening_per_mm])

    def scaled(self, scale: float, width_prior: float | None = None) -> FootprintLaw:
        """The same footprint `scale` times as wide, f(d / scale) (and with another
        width prior when given)."""
        d = np.arange(self.profile.size) * PROFILE_STEP_MM
        profile = np.interp(d / scale, d, self.profile, right=0.0)
        prior = self.width_prior if width_prior is None else float(width_prior)
        return replace(self, profile=profile, sigma_mm=self.sigma_mm * scale, width_prior=prior)

    @classmethod
    def of(cls, heights: HeightModel, method: str = "model") -> FootprintLaw:
        """From a skin's height model (`fruitcli.sensing.skin.heights.HeightModel`: the
        Gaussian law or the crossing table): its contact activation against distance.
        `method`: the detection method that needs it, for the error."""
        sigma = float(getattr(heights, "sigma_mm", np.nan))
        if not np.isfinite(sigma) or sigma <= 0:
            raise FrameError(
                f'[detection].method = "{method}": the skin has no footprint law '
                "([skin].footprint_sigma_mm or the crossing's table)"
            )
        d = np.arange(0.0, 8.0 * WIDTH_BOUNDS[1] * sigma, PROFILE_STEP_MM)
        c = np.asarray(heights.contact_counts(np.zeros(d.size, np.int64), d), dtype=float)
        if not np.all(np.isfinite(c)) or c[0] <= 0:
            raise FrameError(
                f'[detection].method = "{method}": the skin\'s footprint gives no activation '
                "at contact"
            )
        gain = getattr(heights, "gain", None)
        as_gap = float(getattr(heights, "height_as_gap", 0.0))
        decay = float(getattr(heights, "gap_decay_mm", np.inf))
        widening = float(getattr(heights, "widening_per_mm", 0.0))
        return cls(
            np.ascontiguousarray(np.maximum(c / c[0], 0.0)),
            sigma,
            float(heights.noise_std_counts),
            None if gain is None else np.asarray(gain, dtype=float),
            height_distance=float(getattr(heights, "height_as_distance", 1.0)),
            height_gap_per_mm=as_gap / decay if as_gap else 0.0,
            height_widening_per_mm=widening * as_gap,
        )


class Window:
    """The window of grid cells around each taxel (5 x 5 with ``HALF`` = 2): its taxels
    (-1: none), the cells' offsets (di, dj) from the centre and its open sides
    (`_open_sides`)."""

    def __init__(self, i: np.ndarray, j: np.ndarray, half: int | None = None):
        from fruitcli.sensing.detection.model_kernel import map_factors

        half = HALF if half is None else int(half)
        i, j = np.asarray(i, np.int64), np.asarray(j, np.int64)
        h, w = int(i.max()) + 1 + 2 * half, int(j.max()) + 1 + 2 * half
        grid = np.full((h, w), -1, np.int64)
        grid[i + half, j + half] = np.arange(i.size)
        di, dj = np.meshgrid(np.arange(-half, half + 1), np.arange(-half, half + 1), indexing="ij")
        self.di, self.dj = di.ravel(), dj.ravel()
        self.taxels = grid[i[:, None] + half + self.di, j[:, None] + half + self.dj]  # (T, K)
        self.open_sides = _open_sides(self.taxels, self.di, self.dj)  # (T, 2)
        self.i, self.j = i, j
        basis = [np.ones(self.di.size), self.di, self.dj, self.di**2, self.di * self.dj]
        self.basis = np.stack([*basis, self.dj**2], axis=1).astype(float)  # (K, 6)
        near = (np.abs(self.di) <= 1) & (np.abs(self.dj) <= 1)
        self.map_weight = np.where(near, 1.0, RING_WEIGHT)
        self.map_low = np.zeros((i.size, self.basis.shape[1], self.basis.shape[1]))
        self.map_ok = np.zeros(i.size, np.bool_)
        map_factors(self.taxels, self.basis, self.map_weight, self.map_low, self.map_ok)


@dataclass
class Fitted:
    """Per touch: grid coordinates i, j, point (n, 3) mm, its 1-sigma radius (mm), the
    RMS weighted residual, the width scale and the fit's outcome (FIT_MODEL or FIT_N9)."""

    i: np.ndarray
    j: np.ndarray
    xyz_mm: np.ndarray
    pos_err_mm: np.ndarray
    residual: np.ndarray
    width_scale: np.ndarray
    fit: np.ndarray

    def merged(
        self, xyz: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """The touches' points (n, 3) mm (the model's where it placed them, `xyz`, N9's,
        elsewhere), their grid coordinates i, j, and the touch table's fit columns."""
        placed = (self.fit == FIT_MODEL)[:, None]
        columns = {"pos_err_mm": self.pos_err_mm, "residual": self.residual, "fit": self.fit}
        return np.where(placed, self.xyz_mm, xyz), self.i, self.j, columns


def refine(
    frame: np.ndarray,
    centre: np.ndarray,
    i0: np.ndarray,
    j0: np.ndarray,
    peak: np.ndarray,
    v: np.ndarray,
    window: Window,
    positions: Callable[[np.ndarray], np.ndarray],
    law: FootprintLaw,
    n9_taxels: np.ndarray | None = None,
    chart: SurfaceChart | None = None,
    noise: np.ndarray | None = None,
    frames_taken: np.ndarray | None = None,
    rows: np.ndarray | None = None,
) -> Fitted:
    """Fit the touches: frame (n,) row of `v` (F, T) activations (counts, gains divided
    out or not as `law.gain` says), centre (n,) peak taxel, i0, j0 (n,) N9 grid
    coordinates, peak (n,) counts; ``positions(win)`` gives the window taxels' positions
    (n, K, 3) mm for win (n, K) (-1 entries: any position). `n9_taxels` (n, 9): each
    touch's N9 taxels, left out of the other touches of its frame. `chart`: the body's
    surface (`surface_chart.SurfaceChart`, same state), on which the points then run;
    None: on the surface the window's taxels span. `noise` (T,): each taxel's noise
    (counts std, on the scale of `v`); None: the law's one value for all.
    `frames_taken` (n,): how many frames each touch's row of `v` is the mean of
    (`recent_frames`; its noise falls by their square root); None: one. `rows` (n,):
    each touch's row of `v`; None: its frame."""
    from fruitcli.sensing.detection.model_kernel import fit_all

    n = frame.size
    win = np.ascontiguousarray(window.taxels[centre])  # (n, K)
    pos = np.ascontiguousarray(positions(np.where(win >= 0, win, 0)), dtype=float)
    rows = frame if rows is None else rows
    noise_t = _touch_noise(noise, law, v.shape[1], frame, frames_taken)
    vw, inv_e, gain, coef, corr, used = _windows(
        frame, rows, centre, win, n9_taxels, v, law, noise_t, pos, window
    )
    sub = 1
    if chart is not None:
        from fruitcli.sensing.detection.surface_chart import SUB

        corr, sub = chart.corrections(centre, coef), SUB
    ci, cj = window.i[centre], window.j[centre]
    a0 = np.asarray(i0, float) - ci
    b0 = np.asarray(j0, float) - cj
    x0, lo, hi = _start_and_bounds(a0, b0, peak)
    out = np.empty((n, 6))
    cov = np.empty((n, 4, 4))
    xyz = np.empty((n, 3))
    var_mm2 = np.empty(n)
    fit_all(
        x0,
        lo,
        hi,
        vw,
        inv_e,
        gain,
        pos,
        coef,
        corr,
        sub,
        law.profile,
        PROFILE_STEP_MM,
        law.height,
        law.width_prior,
        ITERATIONS,
        out,
        cov,
        xyz,
        var_mm2,
    )
    a, b, s = out[:, 0], out[:, 1], out[:, 3]
    red = out[:, 4] / np.maximum(used - 4, 1)
    fit = (lo, hi, vw, inv_e, gain, pos, coef, corr, sub, law, used)
    sides = window.open_sides[centre]
    spread, swapped = _mirror_spread(out, xyz, red, var_mm2, sides, window, fit)
    err_mm = np.sqrt(np.maximum(var_mm2 * np.maximum(red, 1.0) + spread, 0.0))
    # a touch that took its second fit's point is held to its peak taxel: N9's point lies
    # on the other side of it, where the second fit did not start
    ref_a, ref_b = np.where(swapped, 0.0, a0), np.where(swapped, 0.0, b0)
    kept = _failed(out, err_mm, red, ref_a, ref_b, used, law.width_prior)
    return Fitted(
        np.where(kept, i0, ci + a),
        np.where(kept, j0, cj + b),
        xyz,
        np.where(kept, np.nan, err_mm),
        np.sqrt(red),
        s,
        np.where(kept, FIT_N9, FIT_MODEL).astype(np.int8),
    )


def _windows(
    frame: np.ndarray,
    rows: np.ndarray | None,
    centre: np.ndarray,
    win: np.ndarray,
    n9_taxels: np.ndarray | None,
    v: np.ndarray,
    law: FootprintLaw,
    noise: np.ndarray,
    pos: np.ndarray,
    window: Window,
):
    """`model_kernel.prepare` on the touches' windows: -> their activations, inverse
    errors and gains (n, K), surface maps (n, 6, 3), the maps' misfits at the taxels
    (n, W, W, 3) and the taxels fitted (n,)."""
    from fruitcli.sensing.detection.model_kernel import prepare

    n, k = win.shape
    side = int(round(np.sqrt(k)))
    n9 = np.full((n, 9), -1, np.int64) if n9_taxels is None else n9_taxels
    vw, inv_e, gain = np.empty((n, k)), np.empty((n, k)), np.empty((n, k))
    coef, corr = np.empty((n, 6, 3)), np.empty((n, side, side, 3))
    used = np.empty(n, np.int64)
    taxel_gain = np.ones(v.shape[1]) if law.gain is None else law.gain
    prepare(
        np.ascontiguousarray(frame, dtype=np.int64),
        np.ascontiguousarray(rows, dtype=np.int64),
        np.ascontiguousarray(centre, dtype=np.int64),
        win,
        np.ascontiguousarray(n9, dtype=np.int64),
        np.ascontiguousarray(v, dtype=float),
        np.ascontiguousarray(taxel_gain, dtype=float),
        noise,
        MODEL_ERROR,
        pos,
        window.basis,
        window.map_weight,
        window.map_low,
        window.map_ok,
        vw,
        inv_e,
        gain,
        coef,
        corr,
        used,
    )
    return vw, inv_e, gain, coef, corr, used


def _open_sides(win: np.ndarray, di: np.ndarray, dj: np.ndarray) -> np.ndarray:
    """(T, 2) each window's open side along a and along b: +1 or -1 where the window
    `win` (T, K) of cells at offsets di, dj (K,) has no taxel in the next row of cells on
    that side of its centre taxel (column +1 or -1 of the N9), 0 where both sides have
    one; +1 where both are open. A footprint seen from one side only."""
    have = win >= 0
    near_b, near_a = np.abs(dj) <= 1, np.abs(di) <= 1
    sides = np.zeros((len(win), 2), np.int64)
    for axis, offset, near in ((0, di, near_b), (1, dj, near_a)):
        for d in (-1, 1):
            gone = ~np.any(have & (offset == d) & near, axis=1)
            sides[gone, axis] = d
    return sides


def _mirror_spread(
    out: np.ndarray,
    xyz: np.ndarray,
    red: np.ndarray,
    var_mm2: np.ndarray,
    sides: np.ndarray,
    window: Window,
    fit: tuple,
) -> tuple[np.ndarray, np.ndarray]:
    """((n,) mm^2 to add to each touch's squared 1-sigma radius for a second explanation
    of its frame, (n,) which touches took their second fit's point). Seen from one side
    only (`_open_sides`), a farther point with more amplitude and a nearer one with less
    explain the taxels nearly alike: a touch down a body's flank past the last column,
    and one on the top by that column. With the 3D distance that happens when the taxels
    one row inwards read less than ``MIRROR_UNSEEN`` times their error; with the height
    as gap (the law's ``height_gap_per_mm`` > 0) a flank touch weakens every crossing
    alike and the row inwards reads it too, so every touch at an open side whose point
    is nearer the peak taxel than ``MIRROR_NEAR`` and whose fit leaves more than the
    noise (reduced chi^2 over ``MIRROR_MISFIT``) is also tried (for a flank point). Such
    a touch is fitted again along each such axis, from ``MIRROR_FAR`` grid units out on
    the open side when its point is nearer the peak taxel than ``MIRROR_NEAR``, from the
    peak taxel's row otherwise. When the second fit ends more than ``MIRROR_MIN_MM``
    from the first, with a chi^2 larger by d (scaled by the first's reduced chi^2 when
    over 1), the two points are taken as a two-point posterior, weight w = 1 / (1 +
    exp(d / 2)) on the second. Where d < -``MIRROR_KEEP`` (w over 0.73) and the second
    fit has a position variance, its point is kept: out, xyz, red and var_mm2 (the fits'
    results, points, reduced chi^2 and position variances) are replaced in place, and w
    becomes the first's weight. The radius grows by w D^2, D the points' distance (mm):
    the mean squared distance from the point kept to the posterior's (of the two axes',
    the larger; for a touch that took a second fit's point, that pair's alone). `fit`:
    (lo, hi, v, inv_e, gain, pos, coef, corr, sub, law, used) of `refine`'s fits."""
    from fruitcli.sensing.detection.model_kernel import fit_all

    lo, hi, vw, inv_e, gain, pos, coef, corr, sub, law, used = fit
    spread, swapped = np.zeros(len(out)), np.zeros(len(out), np.bool_)
    if not sides.any():  # no touch at an edge of the grid
        return spread, swapped
    finite = np.isfinite(out).all(axis=1)
    snr = vw * inv_e  # (n, K) each window taxel's activation over its error
    as_gap = law.height_gap_per_mm > 0.0
    touch, starts = [], []
    for axis, offset, across in ((0, window.di, window.dj), (1, window.dj, window.di)):
        inward = (offset[None, :] == -sides[:, axis : axis + 1]) & (np.abs(across) <= 1)
        out_side = sides[:, axis] * out[:, axis]  # grid units out on the open side
        unseen = np.where(inward, snr, 0.0).max(axis=1) < MIRROR_UNSEEN
        unseen |= as_gap & (out_side < MIRROR_NEAR) & (red > MIRROR_MISFIT)
        k = np.flatnonzero(finite & (sides[:, axis] != 0) & unseen)
        x = out[k, :4].copy()
        out_side = out_side[k]
        x[:, axis] = np.where(out_side < MIRROR_NEAR, sides[k, axis] * MIRROR_FAR, 0.0)
        touch.append(k)
        starts.append(x)
    k = np.concatenate(touch)
    if not k.size:
        return spread, swapped
    alt, alt_xyz, alt_var = np.empty((k.size, 6)), np.empty((k.size, 3)), np.empty(k.size)
    fit_all(
        np.clip(np.concatenate(starts), lo[k], hi[k]), lo[k], hi[k], vw[k], inv_e[k],
        gain[k], pos[k], coef[k], corr[k], sub, law.profile, PROFILE_STEP_MM, law.height,
        law.width_prior, ITERATIONS, alt, np.empty((k.size, 4, 4)), alt_xyz, alt_var,
    )  # fmt: skip
    prior = law.width_prior
    dist2 = np.sum((alt_xyz - xyz[k]) ** 2, axis=1)
    valid = ~_off_footprint(alt, prior) & (dist2 > MIRROR_MIN_MM**2)
    chi2 = out[k, 4] + ((out[k, 3] - 1.0) / prior) ** 2
    chi2_alt = alt[:, 4] + ((alt[:, 3] - 1.0) / prior) ** 2
    d = np.where(valid, (chi2_alt - chi2) / np.maximum(red[k], 1.0), np.inf)
    placed = np.isfinite(alt_var) & (alt_var > 0.0)  # a covariance to give the touch
    keep = _kept_seconds(k, np.where(placed, d, np.inf), len(out))  # rows of k kept
    t = k[keep]  # the touches that take their second fit's point
    out[t], xyz[t], var_mm2[t] = alt[keep], alt_xyz[keep], alt_var[keep]
    red[t] = alt[keep, 4] / np.maximum(used[t] - 4, 1)
    spread[t] = dist2[keep] / (1.0 + np.exp(np.minimum(-d[keep] / 2.0, 700.0)))
    swapped[t] = True
    w = 1.0 / (1.0 + np.exp(np.minimum(d / 2.0, 700.0)))
    np.maximum.at(spread, k, np.where(valid & ~swapped[k], w * dist2, 0.0))
    return spread, swapped


def _kept_seconds(k: np.ndarray, d: np.ndarray, n: int) -> np.ndarray:
    """Rows of the second fits of touches k (m,) whose point is kept: their chi^2 lower
    than the first's by more than ``MIRROR_KEEP`` (d, scaled; inf: not to be kept), the
    lowest of a touch's two axes (the first of them on a tie)."""
    best = np.full(n, -MIRROR_KEEP)
    np.minimum.at(best, k, d)
    rows = np.flatnonzero((d < -MIRROR_KEEP) & (d == best[k]))
    return rows[np.unique(k[rows], return_index=True)[1]]


def _start_and_bounds(
    a0: np.ndarray, b0: np.ndarray, peak: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fits' start (n, 4) (a, b, A, s: the N9 point, the peak's counts, width scale 1)
    and their lower and upper bounds (n, 4)."""
    n = len(a0)
    pk = np.maximum(np.asarray(peak, float), 1e-9)
    x0 = np.empty((n, 4))
    x0[:, 0], x0[:, 1], x0[:, 2], x0[:, 3] = a0, b0, pk, 1.0
    lo, hi = np.empty((n, 4)), np.empty((n, 4))
    lo[:, :2], hi[:, :2] = -MAX_SHIFT, MAX_SHIFT
    lo[:, 2], hi[:, 2] = AMPLITUDE_BOUNDS[0] * pk, AMPLITUDE_BOUNDS[1] * pk
    lo[:, 3], hi[:, 3] = WIDTH_BOUNDS
    return x0, lo, hi


def _off_footprint(out: np.ndarray, width_prior: float) -> np.ndarray:
    """Which fits (n,) of `fit_all`'s results out (n, 6) are not finite, end on a bound of
    the point (``MAX_SHIFT``) or have a width scale more than ``MAX_WIDTH_SIGMAS`` priors
    from 1 (not the skin's footprint)."""
    edge = 1e-6
    return (
        ~np.isfinite(out).all(axis=1)
        | (np.abs(out[:, :2]) >= MAX_SHIFT - edge).any(axis=1)
        | (np.abs(out[:, 3] - 1.0) > MAX_WIDTH_SIGMAS * width_prior)
    )


def _failed(
    out: np.ndarray,
    err_mm: np.ndarray,
    red: np.ndarray,
    a0: np.ndarray,
    b0: np.ndarray,
    used: np.ndarray,
    width_prior: float,
) -> np.ndarray:
    """Which fits (n,) fail a test of the module's list, so that N9's point is kept: out
    (n, 6) `fit_all`'s results, err_mm the 1-sigma radii, red the reduced chi^2, a0, b0
    the N9 start, used the taxels fitted, `width_prior` the law's."""
    a, b = out[:, 0], out[:, 1]
    return (
        _off_footprint(out, width_prior)
        | ~np.isfinite(err_mm)
        | (np.hypot(a - a0, b - b0) > 1.0)
        | (used < MIN_TAXELS)
        | (err_mm > MAX_UNCERTAINTY_MM)
        | (red > MAX_REDUCED_CHI2)
    )


def recent_frames(
    history: np.ndarray, rows: np.ndarray, centre: np.ndarray, window: Window, frames: int
) -> tuple[np.ndarray, np.ndarray]:
    """Each touch's activations (n, T) averaged over its frame and those of the
    ``frames - 1`` before it that show the same touch: rows (n,) of `history` (H, T)
    (counts over the baseline, gains divided out or not as the fit's law says, not
    clipped at 0) are the touches' frames, centre (n,) their peak taxels. A frame before
    is taken when its activations over the touch's window point the same way as the
    touch's own (cosine at least ``SAME_TOUCH_COSINE``), going back from the touch's frame
    and stopping at the first that does not: another touch's frames, a moving touch's
    older ones, frames with little more than noise and anything before those are left
    out.
    -> (means clipped at 0, frames taken (n,))."""
    rows = np.asarray(rows, np.int64)
    total = history[rows].copy()
    taken = np.ones(len(rows), np.int64)
    if frames > 1 and len(rows):
        win = window.taxels[centre]  # (n, K)
        inside = win >= 0
        own = np.where(inside, np.take_along_axis(total, np.maximum(win, 0), 1), 0.0)
        own_norm = np.linalg.norm(own, axis=1)
        alive = np.ones(len(rows), bool)  # every frame since the touch's shows it
        for lag in range(1, frames):
            there = rows - lag >= 0
            earlier = history[np.maximum(rows - lag, 0)]  # (n, T)
            seen = np.where(inside, np.take_along_axis(earlier, np.maximum(win, 0), 1), 0.0)
            cosine = np.sum(seen * own, axis=1) / np.maximum(
                np.linalg.norm(seen, axis=1) * own_norm, 1e-12
            )
            same = alive & there & (cosine >= SAME_TOUCH_COSINE)
            alive = same
            if not alive.any():
                break
            total[same] += earlier[same]
            taken += same
    return np.maximum(total / taken[:, None], 0.0), taken


def _touch_noise(
    noise: np.ndarray | None,
    law: FootprintLaw,
    taxels: int,
    frame: np.ndarray,
    frames_taken: np.ndarray | None,
) -> np.ndarray:
    """Each touch's taxel noise (n, T) (counts std): `noise` (T,) or the law's value, over
    the square root of the frames each touch's activations are the mean of."""
    base = np.full(taxels, law.noise_std_counts) if noise is None else np.asarray(noise, float)
    taken = np.ones(len(frame)) if frames_taken is None else np.asarray(frames_taken, float)
    return np.ascontiguousarray(base[None, :] / np.sqrt(taken)[:, None])


@contextmanager
def tuned(half: int, iterations: int) -> Iterator[None]:
    """The model method with another window (``half``: 1 for 3 x 3, 2 for 5 x 5) and
    iteration cap while the block runs (`fruit study locate`'s settings rows). It sets
    this module's ``HALF`` and ``ITERATIONS``, which Locators built and fits run inside
    the block read. Blocks in other threads of the process wait for it (`_TUNED`), so
    model locates run inside such blocks never see another block's settings; a model
    locate run outside any block while one is open would."""
    global HALF, ITERATIONS
    if half < 1 or iterations < 1:
        raise ValueError(
            f"model settings: expected half >= 1 and iterations >= 1, got {half}, {iterations}"
        )
    with _TUNED:
        saved = HALF, ITERATIONS
        HALF, ITERATIONS = int(half), int(iterations)
        try:
            yield
        finally:
            HALF, ITERATIONS = saved


_TUNED = threading.RLock()
