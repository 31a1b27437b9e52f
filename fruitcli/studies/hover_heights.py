"""Hover heights on virtual-bench descents the skin was not calibrated on.

Units: mm, counts.

The board is the flat 21 x 12 grid of `two_fingers` (16 x 12 mm pitches). A calibration
run (seed 0, the small indenter, one sample a quarter pitch off every 3rd inner taxel)
descends from ``START_GAP_MM`` to contact; the gap law and footprint of
`calibrate.fit_skin`'s model (gains 1: the skin is uniform) are fitted to the taxels within
``NEAR_MM`` of each sample (`fit_gap_law`). Each evaluation run descends over other
points (three eighths of a pitch off every inner taxel) in ``STEP_MM`` steps with another
seed, and detects with hovers on (default hover levels from the calibrated noise; the
baseline is the skin's mean counts), heights from the calibration:

- ``other run``: the small indenter;
- ``other indenter``: the medium one (wider footprint) on the small one's calibration;
- ``gain spread``: a skin whose taxel gains spread +-20 %, on the calibration of the
  uniform skin;
- ``calibrated on a gain spread``: the other way round, a uniform skin on a calibration
  recorded on a skin whose gains spread +-20 % (fitted as if uniform).

Per band of true height: the median and 95th percentile of |height - true| of each
frame's strongest row (a touch or a hover); the largest true height at which a hover is
still detected (median over the samples); the position error (mm, to the sample's
contact point) of hovers and of touches.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from fruitcli.sensing.skin.forward import Skin, SkinParams
    from fruitcli.tables import Taxels

START_GAP_MM = 5.0
STEP_MM = 0.1
BANDS = ((0.0, 0.5), (0.5, 1.0), (1.0, 2.0), (2.0, 3.0), (3.0, np.inf))
CALIBRATION_STRIDE = 3  # every 3rd sample point calibrates (64 descents)
NEAR_MM = 20.0  # taxels this near a sample enter the calibration fit
HEADER = ["run", "band_mm", "frames", "median_error_mm", "p95_error_mm"]


def _descents(
    taxels: Taxels, skin: Skin, indenter: str, points: np.ndarray, rng: np.random.Generator
):
    """(counts (N, T), true gap (N,), sample (N,)) of descents over points (P, 3)."""
    from fruitcli.sensing.skin import forward

    gaps = np.arange(START_GAP_MM, -STEP_MM / 2, -STEP_MM)
    counts, gap, sample = [], [], []
    for k, p in enumerate(points):
        dist = np.linalg.norm(taxels.xyz_mm - p, axis=1)
        mean = skin.baseline_counts + forward.activation_counts(dist[None, :], gaps, indenter, skin)
        counts.append(forward.frame_counts(mean, skin.noise_std_counts, rng))
        gap.append(gaps)
        sample.append(np.full(gaps.size, k))
    return np.concatenate(counts), np.concatenate(gap), np.concatenate(sample)


def _points(taxels: Taxels, frac: float) -> np.ndarray:
    inner = (taxels.i >= 1) & (taxels.i <= 19) & (taxels.j >= 1) & (taxels.j <= 10)
    return taxels.xyz_mm[inner] + np.array([16.0, 12.0, 0.0]) * frac


def fit_gap_law(v: np.ndarray, dist_mm: np.ndarray, gap_mm: np.ndarray) -> dict:
    """Least squares of v = A exp(-d^2 / 2 s^2) exp(-gap / l) over the taxels within
    ``NEAR_MM`` of each frame's sample (gains 1: the calibration skin is uniform).
    -> {contact_counts, sigma_mm, gap_decay_mm}."""
    from scipy.optimize import least_squares

    near = dist_mm <= NEAR_MM
    rows = np.nonzero(near)
    vv, dd, gg = v[rows], dist_mm[rows], gap_mm[rows[0]]

    def residual(x: np.ndarray):
        a, s, lam = np.exp(x)
        return a * np.exp(-0.5 * (dd / s) ** 2) * np.exp(-gg / lam) - vv

    res = least_squares(residual, np.log([max(vv.max(), 1.0), 6.0, 2.0]))
    a, s, lam = np.exp(res.x)
    return {"contact_counts": float(a), "sigma_mm": float(s), "gap_decay_mm": float(lam)}


def calibrated(seed: int = 0, gain_spread: float = 0.0) -> tuple[SkinParams, dict, Taxels]:
    """The `forward.SkinParams` fitted to a calibration run on a skin whose taxel gains
    spread +- `gain_spread`, the fit, and the taxels."""
    from fruitcli.sensing.skin import forward
    from fruitcli.studies.two_fingers import _taxels

    taxels = _taxels()
    skin = forward.make_skin(
        len(taxels),
        seed,
        forward.SkinParams(forward.default_footprints_mm(), gain_spread=gain_spread),
    )
    rng = np.random.default_rng(seed)
    points = _points(taxels, 0.25)[::CALIBRATION_STRIDE]
    counts, gap, sample = _descents(taxels, skin, "small", points, rng)
    dist = np.linalg.norm(taxels.xyz_mm[None] - points[sample][:, None], axis=2)
    fit = fit_gap_law(counts - skin.baseline_counts, dist, gap)
    noise = float(np.sqrt(np.mean(skin.noise_std_counts**2)))
    return (
        forward.SkinParams(
            {"small": fit["sigma_mm"]}, fit["contact_counts"], fit["gap_decay_mm"], 0.0, noise
        ),
        fit,
        taxels,
    )


def evaluate(
    params: SkinParams,
    fit: dict[str, float],
    taxels: Taxels,
    name: str,
    indenter: str,
    gain_spread: float,
    seed: int,
) -> tuple[list[list], dict[str, float]]:
    """Rows of HEADER, and (largest hover height, hover and touch position errors)."""
    from fruitcli.sensing.detection.frames_to_touches import Locator, Stream
    from fruitcli.sensing.detection.settings import Settings
    from fruitcli.sensing.detection.touch_table import HOVER, TOUCH
    from fruitcli.sensing.frames.board import default_board
    from fruitcli.sensing.skin import forward
    from fruitcli.sensing.skin.heights import GapLaw

    skin = forward.make_skin(
        len(taxels),
        seed,
        forward.SkinParams(forward.default_footprints_mm(), gain_spread=gain_spread),
    )
    rng = np.random.default_rng(seed)
    points = _points(taxels, 0.375)
    counts, gap, sample = _descents(taxels, skin, indenter, points, rng)
    noise = params.noise_std_counts
    assert isinstance(noise, float)  # the calibration's one std
    law = GapLaw(
        params.contact_counts,
        params.gap_decay_mm,
        params.footprint_sigma_mm["small"],
        noise,
    )
    loc = Locator(taxels, default_board(), taxels.xyz_mm, Settings(hovers=True), heights=law)
    err_l: list[float] = []
    true_l: list[float] = []
    kind_l: list[int] = []
    pos_l: list[float] = []
    top = []
    for k in range(len(points)):
        stream = Stream(loc, skin.baseline_counts.astype(float))
        rows = np.flatnonzero(sample == k)
        seen = []
        for f in rows:
            t = stream.step(counts[f].astype(float))
            if len(t) == 0:
                continue
            n = int(np.argmax(t.peak))
            g = max(gap[f], 0.0)
            err_l.append(abs(t.height_mm[n] - g))
            true_l.append(g)
            kind_l.append(int(t.kind[n]))
            pos_l.append(float(np.linalg.norm(t.xyz_mm[n] - points[k])))
            seen.append(gap[f])
        top.append(max(seen) if seen else np.nan)
    err, true, kind, pos = map(np.asarray, (err_l, true_l, kind_l, pos_l))
    out = []
    for lo, hi in BANDS:
        sel = (true >= lo) & (true < hi) if lo > 0 else (true <= hi)
        e = err[sel]
        label = f"{lo:g}-{hi:g}" if np.isfinite(hi) else f"{lo:g}+"
        out.append(
            [
                name,
                label,
                int(sel.sum()),
                float(np.median(e)) if e.size else float("nan"),
                float(np.percentile(e, 95)) if e.size else float("nan"),
            ]
        )
    extra = {
        "largest_hover_mm": float(np.nanmedian(top)),
        "hover_position_error_mm": float(np.median(pos[kind == HOVER])),
        "touch_position_error_mm": float(np.median(pos[kind == TOUCH])),
    }
    return out, extra


RUNS = (  # name, indenter, gain spread of the skin, seed, gain spread of the calibration
    ("other run", "small", 0.0, 1, 0.0),
    ("other indenter", "medium", 0.0, 2, 0.0),
    ("gain spread 0.2", "small", 0.2, 3, 0.0),
    ("calibrated on a gain spread 0.2", "small", 0.0, 4, 0.2),
)


def write(out_dir: str | Path) -> dict:
    """Calibrate, evaluate every run; write hover_heights.csv and hover_heights.md."""
    from fruitcli.fsutil import staged_dir, write_csv, write_text

    cals = {spread: calibrated(0, spread) for spread in sorted({r[4] for r in RUNS})}
    rows, extras = [], {}
    for name, indenter, spread, seed, cal_spread in RUNS:
        params, fit, taxels = cals[cal_spread]
        r, extra = evaluate(params, fit, taxels, name, indenter, spread, seed)
        rows += r
        extras[name] = extra
    lines = ["# Hover heights on descents the skin was not calibrated on", ""]
    for spread, (_, fit, _) in cals.items():
        lines.append(
            f"- Calibration on a skin with gains spread +-{spread:g} (small indenter, seed "
            f"0): footprint {fit['sigma_mm']:.2f} mm, contact {fit['contact_counts']:.1f} "
            f"counts, gap decay {fit['gap_decay_mm']:.2f} mm."
        )
    lines += [
        "",
        "| run | true height (mm) | frames | median error (mm) | p95 error (mm) |",
        "|---|---|---|---|---|",
    ]
    lines += [f"| {r[0]} | {r[1]} | {r[2]} | {r[3]:.2f} | {r[4]:.2f} |" for r in rows]
    lines += [
        "",
        "| run | largest height still detected (mm, median) | hover position "
        "error (mm, median) | touch position error (mm, median) |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {k} | {e['largest_hover_mm']:.2f} | {e['hover_position_error_mm']:.2f} | "
        f"{e['touch_position_error_mm']:.2f} |"
        for k, e in extras.items()
    ]
    with staged_dir(out_dir) as tmp:
        write_csv(
            tmp / "hover_heights.csv",
            HEADER,
            rows,
            comments=["|height - true height| of each frame's strongest row, mm"],
        )
        write_text(tmp / "hover_heights.md", "\n".join(lines) + "\n")
    return {"rows": rows, "extras": extras}
