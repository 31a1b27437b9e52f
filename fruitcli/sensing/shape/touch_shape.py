"""What a touch carries besides its position: strength, footprint size and hover height.

Units: counts, mm.

From the activation v of a touch's N9 cells (peak taxel in the middle) and the taxels'
positions:

- centre and size: along each grid axis through the peak (its two neighbours at a and b
  mm), a parabola through ln v gives the Gaussian footprint's centre offset and width,
  sigma^2 = -1 / (2 c2); an axis whose neighbours have no taxel or v <= ``MIN_COUNTS``
  is left out (with one usable neighbour the skin's width places the centre).
  ``size_mm`` is the footprint's sigma (the quantity of
  ``[skin].footprint_sigma_mm``) from the mean curvature of the axes used, NaN when
  neither axis could be used;
- strength: the least-squares amplitude of the skin's contact activation around that
  centre, s = sum v m / sum m^2 over the N9 taxels (m: `HeightModel.contact_counts`);
  1 at contact, below 1 hovering, above for a firm press. Its noise: std / sqrt(sum m^2);
- height: the skin's law for s (`HeightModel.height_mm`), with its uncertainty.

The reported position stays the N9 centroid; the fitted centre is used only here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from fruitcli.sensing.skin.heights import GapLaw, HeightModel

MIN_COUNTS = 0.5  # a neighbour below this gives no log
_AXES = ((1, 7), (3, 5))  # N9 cells either side of the centre (4): along i, along j


@dataclass
class Shapes:
    """Per touch: strength (1 = contact), size (footprint sigma, mm), height (mm) and its
    uncertainty (mm)."""

    strength: np.ndarray
    size_mm: np.ndarray
    height_mm: np.ndarray
    height_err_mm: np.ndarray


def footprint_fit(
    v9: np.ndarray, pos9: np.ndarray, xyz: np.ndarray, sigma_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """(centre (n, 3) mm, size (n,) mm) of N9 activations v9 (n, 9) at taxel positions
    pos9 (n, 9, 3), starting from the reported points xyz (n, 3). An axis with one usable
    neighbour only places the centre with the skin's footprint width `sigma_mm`."""
    centre = np.array(xyz, dtype=float)
    curv_sum = np.zeros(len(v9))
    used = np.zeros(len(v9))
    lv = np.log(np.maximum(v9, MIN_COUNTS))
    for lo, hi in _AXES:
        da, db = pos9[:, 4] - pos9[:, lo], pos9[:, hi] - pos9[:, 4]
        a, b = np.linalg.norm(da, axis=1), np.linalg.norm(db, axis=1)
        has_lo = (v9[:, lo] > MIN_COUNTS) & (a > 0)
        has_hi = (v9[:, hi] > MIN_COUNTS) & (b > 0)
        a, b = np.where(a > 0, a, 1.0), np.where(b > 0, b, 1.0)
        up, down = (lv[:, hi] - lv[:, 4]) / b, (lv[:, 4] - lv[:, lo]) / a
        c2 = (up - down) / (a + b)
        both = has_lo & has_hi & (c2 < 0)
        c2 = np.where(both, c2, -1.0)
        delta = -(up - c2 * b) / (2 * c2)
        # one neighbour at x_n (signed): ln v0 - ln v_n = (x_n^2 - 2 x_n delta) / (2 sigma^2)
        xn = np.where(has_hi & ~has_lo, b, -a)
        ln_ratio = lv[:, 4] - np.where(has_hi & ~has_lo, lv[:, hi], lv[:, lo])
        one = (has_lo ^ has_hi) & ~both
        delta = np.where(one, (xn**2 - 2 * sigma_mm**2 * ln_ratio) / (2 * xn), delta)
        ok = both | one
        delta = np.clip(delta, -a / 2, b / 2)
        u = (da + db) / (a + b)[:, None]
        u /= np.maximum(np.linalg.norm(u, axis=1), 1e-12)[:, None]
        along = np.einsum("nd,nd->n", pos9[:, 4] - centre, u) + delta
        centre += np.where(ok, along, 0.0)[:, None] * u
        curv_sum += np.where(both, -2 * c2, 0.0)
        used += both
    with np.errstate(divide="ignore", invalid="ignore"):
        size = np.where(used > 0, np.sqrt(used / curv_sum), np.nan)
    return centre, size


def gap_law_shapes(
    v9: np.ndarray, taxel9: np.ndarray, pos9: np.ndarray, xyz: np.ndarray, law: GapLaw
) -> Shapes:
    """`touch_shapes` for a `heights.GapLaw`, compiled (`shape_kernel`)."""
    from fruitcli.sensing.shape.shape_kernel import gap_law_shapes as kernel

    out = np.empty((len(v9), 4))
    kernel(
        np.ascontiguousarray(v9, dtype=float),
        np.ascontiguousarray(taxel9, np.int64),
        np.ascontiguousarray(pos9, dtype=float),
        np.ascontiguousarray(xyz, dtype=float),
        *_law_arguments(law, taxel9),
        out,
    )
    return Shapes(out[:, 0], out[:, 1], out[:, 2], out[:, 3])


def frame_shapes(
    counts: np.ndarray,
    frame: np.ndarray,
    cell: np.ndarray,
    baseline: np.ndarray,
    divide: np.ndarray | None,
    taxel9: np.ndarray,
    pos: np.ndarray,
    pos_row: np.ndarray,
    xyz: np.ndarray,
    model: HeightModel,
) -> Shapes:
    """`touch_shapes` of touches read from frames: counts (N, R * C), touch k in frame
    frame[k], taxel t in cell cell[t] with C0 baseline[t] counts and its activation divided
    by divide[t] (None: not), taxels taxel9 (n, 9) (-1: none), N9 positions
    pos[pos_row] (n, 9, 3) mm. Compiled in one pass for a `heights.GapLaw`."""
    from fruitcli.sensing.skin.heights import GapLaw

    if len(taxel9) == 0:
        e = np.zeros(0)
        return Shapes(e, e, e, e)
    if type(model) is not GapLaw:
        tax = np.where(taxel9 < 0, 0, taxel9)
        v9 = np.maximum(counts[frame[:, None], cell[tax]] - np.asarray(baseline)[tax], 0.0)
        v9 = v9 * (taxel9 >= 0)
        if divide is not None:
            v9 = v9 / divide[tax]
        return touch_shapes(v9, taxel9, pos[pos_row], xyz, model)
    from fruitcli.sensing.shape.shape_kernel import gathered_shapes

    law = model
    out = np.empty((len(taxel9), 4))
    gathered_shapes(
        counts,
        np.ascontiguousarray(frame, np.int64),
        np.ascontiguousarray(cell, np.int64),
        np.ascontiguousarray(baseline, dtype=float),
        np.zeros(0) if divide is None else np.ascontiguousarray(divide, dtype=float),
        np.ascontiguousarray(taxel9, np.int64),
        np.ascontiguousarray(pos, dtype=float),
        np.ascontiguousarray(pos_row, np.int64),
        np.ascontiguousarray(xyz, dtype=float),
        *_law_arguments(law, taxel9),
        out,
    )
    return Shapes(out[:, 0], out[:, 1], out[:, 2], out[:, 3])


def _law_arguments(
    law: GapLaw, taxel9: np.ndarray
) -> tuple[float, float, float, float, np.ndarray, float]:
    """The compiled kernels' trailing arguments for a `heights.GapLaw`: contact counts,
    gap decay (mm), footprint sigma (mm), noise std (counts), gains per taxel (unit gains
    up to taxel9's largest index when the law has none) and MIN_COUNTS."""
    gain = law.gain if law.gain is not None else _ones(int(taxel9.max()) + 1)
    return (
        float(law.contact),
        float(law.gap_decay_mm),
        float(law.sigma_mm),
        float(law.noise_std_counts),
        np.asarray(gain, dtype=float),
        MIN_COUNTS,
    )


_ONES = np.ones(0)


def _ones(n: int) -> np.ndarray:
    """Unit gains for taxels 0 .. n - 1 (one array, grown when needed)."""
    global _ONES
    if _ONES.size < n:
        _ONES = np.ones(max(n, 1024))
    return _ONES


def touch_shapes(
    v9: np.ndarray, taxel9: np.ndarray, pos9: np.ndarray, xyz: np.ndarray, model: HeightModel
) -> Shapes:
    """Shapes of touches from their N9 activations v9 (n, 9) counts (0 where no taxel),
    taxels taxel9 (n, 9) (-1: none), positions pos9 (n, 9, 3) mm and reported points xyz
    (n, 3) mm, through a `fruitcli.sensing.skin.heights.HeightModel`."""
    n = len(v9)
    if n == 0:
        e = np.zeros(0)
        return Shapes(e, e, e, e)
    from fruitcli.sensing.skin.heights import GapLaw

    if type(model) is GapLaw:
        return gap_law_shapes(v9, taxel9, pos9, xyz, model)
    centre, size = footprint_fit(v9, pos9, xyz, model.sigma_mm)
    dist = np.linalg.norm(pos9 - centre[:, None, :], axis=2)
    m = model.contact_counts(np.maximum(taxel9, 0), dist) * (taxel9 >= 0)
    mm = np.einsum("nk,nk->n", m, m)
    strength = np.einsum("nk,nk->n", v9, m) / mm
    err = model.noise_std_counts / np.sqrt(mm)
    h, h_err = model.height_mm(strength, err)
    return Shapes(strength, size, h, h_err)
