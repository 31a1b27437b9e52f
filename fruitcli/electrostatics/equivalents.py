"""The phenomenological skin's parameters derived from the crossing's table, so the two
models compare number to number (`fruitcli.sensing.skin.forward`).

Units: mm, fF, counts. For each object: the footprint sigma of a Gaussian
A exp(-(dx^2 + dy^2) / (2 sigma^2)) fitted (least squares) to -dC at contact over
offsets up to a pitch (the reach of an N9 window); the gap at
which -dC under the crossing falls to 1/e of its contact value (log-linear between the
table's gaps; beyond the table, the exponential through its last two gaps); the
activation at contact in counts; the gap at which it falls to the threshold. A gap
found beyond the table's last one is named under `extrapolated`.
"""

from __future__ import annotations

from typing import TypedDict

import numpy as np

from fruitcli.electrostatics.crossing import (
    BEND_SHIFT_COUNTS,
    PAD_BEND_CURVATURE_PER_MM,
    TABLE_PITCHES,
    THRESHOLD_COUNTS,
    CrossingTable,
)
from fruitcli.errors import SolverError


def footprint_sigma_mm(dx: np.ndarray, dy: np.ndarray, drop: np.ndarray) -> float:
    """Sigma (mm) of the isotropic Gaussian through `drop` (x, y) >= 0 at offsets dx, dy."""
    from scipy.optimize import curve_fit

    gx, gy = np.meshgrid(dx, dy, indexing="ij")
    r2 = (gx**2 + gy**2).ravel()

    def model(r2_: np.ndarray, amp: float, sigma: float):
        return amp * np.exp(-0.5 * r2_ / sigma**2)

    guess = (float(drop.max()), float(max(np.ptp(dx), np.ptp(dy))) / 4)
    (amp, sigma), _ = curve_fit(model, r2, drop.ravel(), p0=guess, maxfev=10000)
    return float(abs(sigma))


def decay_gap_mm(gaps: np.ndarray, drop: np.ndarray, level: float) -> float:
    """Gap (mm) at which `drop` (g,) (positive, falling with the gap) reaches `level`."""
    if not drop[0] > 0 or not level > 0:
        return float("nan")
    logd = np.log(np.maximum(drop, 1e-300))
    target = np.log(level)
    if target >= logd[0]:
        return 0.0
    below = np.flatnonzero(logd <= target)
    if below.size:
        j = below[0]
        return float(np.interp(target, [logd[j], logd[j - 1]], [gaps[j], gaps[j - 1]]))
    slope = (logd[-1] - logd[-2]) / (gaps[-1] - gaps[-2])
    if slope >= 0:
        return float("inf")
    return float(gaps[-1] + (target - logd[-1]) / slope)


def counts_per_ff(table: CrossingTable) -> tuple[float, dict]:
    """Counts per fF so the crossing bent as the paper's pad shifts BEND_SHIFT_COUNTS, and
    what it was fitted to. The paper does not say along which yarn its pad was bent, and
    10 counts is its largest shift: the larger of the two bends' shifts is set to it."""
    i = int(np.argmin(np.abs(table.curvature_per_mm - PAD_BEND_CURVATURE_PER_MM)))
    shifts = table.c_bend_ff[:, i] - table.c0_ff
    axis = int(np.argmax(np.abs(shifts)))
    shift = float(shifts[axis])
    if shift == 0 or not np.isfinite(shift):
        raise SolverError(
            "crossing cell: bending does not change C0; counts per fF cannot "
            "be fitted to the bent pad"
        )
    scale = BEND_SHIFT_COUNTS / abs(shift)
    return scale, {
        "observation": "paper Fig. 9: the 4 x 4 pad bent 180 deg over its 48 mm "
        "active length shifts its baseline by at most 10 counts",
        "deformation": table.deformations[2 + axis],
        "curvature_per_mm": float(table.curvature_per_mm[i]),
        "shift_ff": shift,
        "counts": BEND_SHIFT_COUNTS,
        "other_bend_shift_ff": float(shifts[1 - axis]),
    }


class ObjectEquivalent(TypedDict):
    """A touch object's Gaussian equivalent in summary.json: footprint sigma (mm), gap
    decay (mm), counts and drop (fF) at contact, the gap (mm) where it falls to the
    threshold, and which of the two gaps lie beyond the table's largest gap."""

    footprint_sigma_mm: float
    gap_decay_mm: float
    contact_counts: float
    contact_dc_ff: float
    threshold_gap_mm: float
    extrapolated: list[str]


def summarize(table: CrossingTable) -> dict:
    """summary.json's content (without the run's inputs)."""
    scale, fit = counts_per_ff(table)
    pitch_x = table.dx_mm.max() / TABLE_PITCHES
    pitch_y = table.dy_mm.max() / TABLE_PITCHES
    quad_x = (table.dx_mm >= 0) & (table.dx_mm <= pitch_x + 1e-9)  # an N9 window's reach
    quad_y = (table.dy_mm >= 0) & (table.dy_mm <= pitch_y + 1e-9)
    centre_x = int(np.flatnonzero(table.dx_mm == 0)[0])
    centre_y = int(np.flatnonzero(table.dy_mm == 0)[0])
    objects: dict[str, ObjectEquivalent] = {}
    for k, name in enumerate(table.objects):
        drop = -table.dc_ff[k]  # (g, x, y)
        contact = drop[0][np.ix_(quad_x, quad_y)]
        under = drop[:, centre_x, centre_y]
        counts = scale * under
        sigma = footprint_sigma_mm(table.dx_mm[quad_x], table.dy_mm[quad_y], contact)
        decay = decay_gap_mm(table.gap_mm, under, under[0] / np.e)
        threshold = decay_gap_mm(table.gap_mm, counts, THRESHOLD_COUNTS)
        gaps = (("gap_decay_mm", decay), ("threshold_gap_mm", threshold))
        objects[name] = ObjectEquivalent(
            footprint_sigma_mm=sigma,
            gap_decay_mm=decay,
            contact_counts=float(counts[0]),
            contact_dc_ff=float(-under[0]),
            threshold_gap_mm=threshold,
            extrapolated=[k for k, gap in gaps if gap > table.gap_mm[-1]],
        )
    shifts = {}
    for a, axis in enumerate(("x", "y")):
        shifts[f"stretch_{axis}"] = (-scale * (table.c_stretch_ff[a] - table.c0_ff)).tolist()
        shifts[f"bend_{axis}"] = (-scale * (table.c_bend_ff[a] - table.c0_ff)).tolist()
    return {
        "c0_ff": table.c0_ff,
        "counts_per_ff": scale,
        "counts_fit": fit,
        "objects": objects,
        "deformation_shift_counts": {
            "strain": table.strain.tolist(),
            "curvature_per_mm": table.curvature_per_mm.tolist(),
            **shifts,
        },
        "threshold_counts": THRESHOLD_COUNTS,
        "mesh": table.mesh_info,
        "mesh_s": table.times_s.get("mesh_s"),
        "solve_s": table.times_s.get("solve_s"),
    }
