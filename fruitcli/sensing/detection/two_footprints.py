"""Two fingers close together: fit one and two footprints of the calibrated skin around
each peak (``[detection].method = "fit2"``).

Units: grid units (taxel pitches) and counts; the footprint's width is the skin's
(``[skin].footprint_sigma_mm`` over the taxels' mean pitch along i and along j).

The paper's multitouch zeroes the strongest touch's N9 and looks again, so two fingers
less than about two pitches apart give one touch. Here every local maximum above the
threshold (`detect.local_peaks`) is a candidate; on the taxels within ``WINDOW`` cells of
it (and nearer it than any other candidate), less the other candidates' footprints (each
its peak's counts at its peak's cell), the activation is fitted (least squares) by one
footprint, A g(c - p), and by two, A1 g(c - p1) + A2 g(c - p2), with g the skin's
radial footprint: the model method's (`model_fit.FootprintLaw`: the Gaussian law's, or
the crossing table's contact profile with ``[skin].model = "electrostatic"``) at the
taxels' pitches, or without one a Gaussian of the calibrated width. The two are kept when

- the fit improves by more than ``MIN_GAIN_SIGMA2`` noise variances and leaves at most
  ``MAX_RESIDUAL_SHARE`` of the one-footprint residual,
- both amplitudes exceed half the threshold, the two are ``MIN_SEPARATION`` apart and
  within the window, and neither is within ``MIN_OTHER`` pitches of another candidate;

each is then placed on the grid by bilinear weights over its four nearest taxels (so it
maps to 3D as the N9 centroid does). Otherwise the candidate is the paper's N9
centroid, unchanged: a single touch is where the N9 method puts it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fruitcli.sensing.detection.detect import MAX_TOUCHES, Grid, Touches, _centroids, local_peaks

WINDOW = 2  # cells either side of the peak that are fitted
MIN_GAIN_SIGMA2 = 30.0  # the two-footprint fit must remove this many noise variances
MAX_RESIDUAL_SHARE = 0.35  # ... and leave at most this share of the one-footprint residual
MIN_SEPARATION = 0.3  # grid units between the two footprints
MIN_OTHER = 1.5  # grid units from a split footprint to any other candidate
MAX_EVALUATIONS = 60  # least-squares iterations per fit at most
_STARTS = ((1.0, 0.0), (0.0, 1.0), (0.7071, 0.7071), (0.7071, -0.7071))  # split directions


@dataclass(frozen=True)
class Footprint:
    """The skin's footprint on the grid: Gaussian widths in grid units and the noise;
    with `profile`, the skin's own radial footprint f(d) (f(0) = 1, sampled every
    `step_mm`: the model method's `model_fit.FootprintLaw`, the Gaussian law's or the
    crossing table's contact profile) at distance d = hypot(di * pitch_i, dj * pitch_j)
    mm replaces the Gaussian."""

    sigma_i: float
    sigma_j: float
    noise_std_counts: float
    profile: np.ndarray | None = None
    step_mm: float = 1.0
    pitch_i: float = 1.0
    pitch_j: float = 1.0

    @classmethod
    def from_taxels(
        cls,
        sigma_mm: float,
        noise_std_counts: float,
        i: np.ndarray,
        j: np.ndarray,
        xyz_mm: np.ndarray,
        profile: np.ndarray | None = None,
        step_mm: float = 1.0,
    ) -> Footprint:
        """Widths from the taxels' mean spacing between grid neighbours along i and j
            (mm per grid unit, also the pitches `profile` is measured with); a `profile` that
        is the Gaussian of `sigma_mm` is dropped for the closed form."""
        cell = {(int(a), int(b)): k for k, (a, b) in enumerate(zip(i, j, strict=True))}

        def pitch(di: int, dj: int) -> float:
            d = [
                np.linalg.norm(xyz_mm[k] - xyz_mm[cell[(a + di, b + dj)]])
                for (a, b), k in cell.items()
                if (a + di, b + dj) in cell
            ]
            return float(np.mean(d)) if d else 1.0

        pi, pj = pitch(1, 0), pitch(0, 1)
        if profile is not None:
            d = np.arange(profile.size) * step_mm
            if np.allclose(profile, np.exp(-0.5 * (d / sigma_mm) ** 2), rtol=0.0, atol=1e-9):
                profile = None  # the Gaussian law's: its closed form, 2-3 times faster
        return cls(sigma_mm / pi, sigma_mm / pj, noise_std_counts, profile, step_mm, pi, pj)


def _shape(ci: np.ndarray, cj: np.ndarray, pi: float, pj: float, fp: Footprint):
    """One footprint at (pi, pj) on cells (ci, cj): (g, dg/dpi, dg/dpj)."""
    if fp.profile is None:
        g = np.exp(-0.5 * (((ci - pi) / fp.sigma_i) ** 2 + ((cj - pj) / fp.sigma_j) ** 2))
        return g, g * (ci - pi) / fp.sigma_i**2, g * (cj - pj) / fp.sigma_j**2
    dx, dy = (ci - pi) * fp.pitch_i, (cj - pj) * fp.pitch_j
    d = np.hypot(dx, dy)
    u = d / fp.step_mm
    last = fp.profile.size - 1
    k = np.minimum(u.astype(np.int64), last - 1)
    t = np.clip(u - k, 0.0, 1.0)
    lo, hi = fp.profile[k], fp.profile[k + 1]
    beyond = u >= last
    g = np.where(beyond, 0.0, lo + t * (hi - lo))
    slope = np.where(beyond, 0.0, (hi - lo) / fp.step_mm)  # df/dd per mm
    inv = np.where(d > 0, 1.0 / np.maximum(d, 1e-12), 0.0)
    return g, -slope * dx * inv * fp.pitch_i, -slope * dy * inv * fp.pitch_j


def _model(x: np.ndarray, ci: np.ndarray, cj: np.ndarray, fp: Footprint):
    """Sum of footprints (A, i, j) in x at cells (ci, cj)."""
    out = np.zeros(ci.shape)
    for k in range(0, len(x), 3):
        a, pi, pj = x[k : k + 3]
        out += a * _shape(ci, cj, pi, pj, fp)[0]
    return out


def _jacobian(x: np.ndarray, ci: np.ndarray, cj: np.ndarray, fp: Footprint):
    """d model / d (A, i, j) of each footprint, (cells, len(x))."""
    jac = np.empty((ci.size, len(x)))
    for k in range(0, len(x), 3):
        a, pi, pj = x[k : k + 3]
        g, gi, gj = _shape(ci, cj, pi, pj, fp)
        jac[:, k] = g
        jac[:, k + 1] = a * gi
        jac[:, k + 2] = a * gj
    return jac


def _fit(v: np.ndarray, ci: np.ndarray, cj: np.ndarray, fp: Footprint, x0: np.ndarray):
    from scipy.optimize import least_squares

    res = least_squares(
        lambda x: _model(x, ci, cj, fp) - v,
        x0,
        method="lm",
        jac=lambda x: _jacobian(x, ci, cj, fp),
        max_nfev=MAX_EVALUATIONS,
    )
    return res.x, float(np.sum(res.fun**2))


def split(
    v: np.ndarray,
    ci: np.ndarray,
    cj: np.ndarray,
    peak_ij: tuple[float, float],
    fp: Footprint,
    threshold: float,
    extent: tuple[float, float] = (np.inf, np.inf),
) -> np.ndarray | None:
    """The two footprints (2, 3) = (A, i, j) fitted to activations v at cells (ci, cj)
    around the peak at `peak_ij`, or None when one footprint explains them, when fewer
    than six cells (two footprints' parameters) are there to fit (a peak in a corner) or
    when a footprint falls outside the taxel grid, 0 <= i <= extent[0], 0 <= j <=
    extent[1] (a finger off the skin's edge cannot be placed on it)."""
    if v.size < 6:
        return None
    pi, pj = peak_ij
    one, rss1 = _fit(v, ci, cj, fp, np.array([v.max(), pi, pj]))
    if rss1 <= MIN_GAIN_SIGMA2 * fp.noise_std_counts**2:
        return None  # one footprint within the noise: nothing to split
    best, rss2 = None, np.inf
    for ui, uj in _STARTS:
        h = 0.5
        x0 = np.array(
            [
                one[0] / 2,
                one[1] - h * ui,
                one[2] - h * uj,
                one[0] / 2,
                one[1] + h * ui,
                one[2] + h * uj,
            ]
        )
        x, rss = _fit(v, ci, cj, fp, x0)
        if rss < rss2:
            best, rss2 = x, rss
    if best is None:
        return None  # no start gave a finite residual
    two = best.reshape(2, 3)
    gain = rss1 - rss2
    sep = np.hypot(two[0, 1] - two[1, 1], two[0, 2] - two[1, 2])
    inside = np.all(np.abs(two[:, 1] - pi) <= WINDOW) and np.all(np.abs(two[:, 2] - pj) <= WINDOW)
    inside = inside and np.all((two[:, 1] >= 0) & (two[:, 1] <= extent[0]))
    inside = inside and np.all((two[:, 2] >= 0) & (two[:, 2] <= extent[1]))
    if (
        gain > MIN_GAIN_SIGMA2 * fp.noise_std_counts**2
        and rss2 <= MAX_RESIDUAL_SHARE * rss1
        and two[:, 0].min() > threshold / 2
        and sep >= MIN_SEPARATION
        and inside
    ):
        return two
    return None


def bilinear_window(fi: float, fj: float, grid: Grid) -> tuple[np.ndarray, np.ndarray, int]:
    """(taxel (9,), weight (9,), centre cell) placing grid point (fi, fj) on the N9 window
    of its nearest taxel cell by bilinear weights (cells without a taxel left out)."""
    h, w = grid.shape
    ci = int(np.clip(np.rint(fi), 0, h - 3))
    cj = int(np.clip(np.rint(fj), 0, w - 3))
    centre = (ci + 1) * w + (cj + 1)
    tax = grid.taxel_of_cell[centre + grid.offsets]
    di, dj = fi - ci, fj - cj
    wi = {-1: max(-di, 0.0), 0: 1 - abs(di), 1: max(di, 0.0)}
    wj = {-1: max(-dj, 0.0), 0: 1 - abs(dj), 1: max(dj, 0.0)}
    weight = np.array([wi[a] * wj[b] for a in (-1, 0, 1) for b in (-1, 0, 1)])
    weight = np.where(tax >= 0, weight, 0.0)
    weight /= max(weight.sum(), 1e-12)
    return tax, weight, centre


def fit2_touches(
    flat: np.ndarray, grid: Grid, threshold: float, fp: Footprint, max_touches: int = MAX_TOUCHES
) -> Touches:
    """Touches of activation grids flat (N, H * W) (see the module docstring)."""
    h, w = grid.shape
    f, cells = local_peaks(flat, grid, threshold)
    rows: dict[str, list[float | np.ndarray]] = {
        k: [] for k in ("frame", "rank", "i", "j", "peak", "taxel", "weight")
    }
    ci_all, cj_all = np.divmod(np.arange(h * w), w)
    for frame in np.unique(f):
        mine = cells[f == frame]
        mine = mine[np.argsort(-flat[frame, mine], kind="stable")][:max_touches]
        peaks_ij = np.column_stack(np.divmod(mine, w)) - 1.0
        out = []
        for n, cell in enumerate(mine):
            pi, pj = peaks_ij[n]
            near = (
                (np.abs(ci_all - 1 - pi) <= WINDOW)
                & (np.abs(cj_all - 1 - pj) <= WINDOW)
                & (grid.taxel_of_cell >= 0)
            )
            own = np.hypot(ci_all - 1 - pi, cj_all - 1 - pj)
            others = np.delete(peaks_ij, n, axis=0)
            for qi, qj in others:  # cells nearer another peak are its
                near &= own < np.hypot(ci_all - 1 - qi, cj_all - 1 - qj)
            ci, cj = ci_all[near] - 1.0, cj_all[near] - 1.0
            rest = _model(
                np.column_stack([np.delete(flat[frame, mine], n), others]).ravel(), ci, cj, fp
            )
            two = split(flat[frame, near] - rest, ci, cj, (pi, pj), fp, threshold, (h - 3, w - 3))
            windows = [] if two is None else [bilinear_window(fi, fj, grid) for _, fi, fj in two]
            if any(wt.sum() == 0 for _, wt, _ in windows):
                two = None  # no taxel among a footprint's four nearest cells
            if (
                two is not None
                and len(others)
                and min(np.hypot(*(others - two[k, 1:]).T).min() for k in range(2)) < MIN_OTHER
            ):
                two = None
            if two is None:
                i, j, tax, wt, _ = _centroids(flat, np.array([frame]), np.array([cell]), grid, 0.0)
                out.append((flat[frame, cell], i[0], j[0], tax[0], wt[0]))
            else:
                for k in np.argsort(-two[:, 0]):
                    a, fi, fj = two[k]
                    tax, wt, _ = windows[k]
                    out.append((a, fi, fj, tax, wt))
        out.sort(key=lambda r: -r[0])
        for rank, (pk, i, j, tax, wt) in enumerate(out[:max_touches]):
            for key, val in zip(rows, (frame, rank, i, j, pk, tax, wt), strict=True):
                rows[key].append(val)
    if not rows["frame"]:
        return Touches.empty()
    return Touches(
        np.array(rows["frame"], np.int64),
        np.array(rows["rank"], np.int64),
        np.array(rows["i"], float),
        np.array(rows["j"], float),
        np.array(rows["peak"], float),
        np.array(rows["taxel"], np.int64),
        np.array(rows["weight"], float),
    )
