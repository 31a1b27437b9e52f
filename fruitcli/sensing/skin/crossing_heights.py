"""Heights from the electrostatic skin (``[skin].model = "electrostatic"``): the
`heights.HeightModel` of the crossing's table (`crossing_skin.CrossingSkin`).

Units: mm, counts.

- Contact activation of a taxel d mm from the contact point: the table's drop at gap 0
  and lateral offset d along the grid's x axis (the table's footprint taken as round:
  its x profile), times the taxel's gain when measured gains are given.
- Height for a strength s: the gap g at which the table's drop right under the crossing
  has fallen to s times its contact value, P(g) = drop(0, 0, g) / drop(0, 0, 0), read
  off P on ``PROFILE_POINTS`` gaps from 0 to the table's last gap plus
  ``TAIL_DECAYS`` of its tail decay (linear between them; beyond, the tail's
  exponential); 0 for s >= 1. Its uncertainty: the strength's times |dg/dP| there.
- The footprint width (fit2, touch sizes) is the table's Gaussian fitted at contact.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin
    from fruitcli.sensing.skin.forward import SkinParams

PROFILE_POINTS = 400
TAIL_DECAYS = 4.0


@dataclass(frozen=True)
class CrossingHeights:
    """Height model of a crossing table for one indenter (see the module docstring)."""

    table: CrossingSkin
    indenter: str
    noise_std_counts: float
    sigma_mm: float
    gap_mm: np.ndarray  # (P,) the profile's gaps, increasing from 0
    profile: np.ndarray  # (P,) P(g), decreasing from 1
    tail_decay_mm: float
    gain: np.ndarray | None = None  # (T,) taxel gains, None: 1 (or activations divided)

    @classmethod
    def of(
        cls,
        table: CrossingSkin,
        indenter: str,
        noise_std_counts: float,
        gain: np.ndarray | None = None,
    ) -> CrossingHeights:
        k = table.object_index(indenter)
        tail = float(table.tail_decay_mm[k])
        gaps = np.linspace(0.0, float(table.gap_mm[-1]) + TAIL_DECAYS * tail, PROFILE_POINTS)
        under = table.drop(indenter, 0.0, 0.0, gaps)
        profile = np.minimum.accumulate(under / under[0])  # falling with the gap
        return cls(
            table,
            indenter,
            float(noise_std_counts),
            float(table.sigma_mm[k]),
            gaps,
            profile,
            tail,
            gain,
        )

    def contact_counts(self, taxel: np.ndarray, dist_mm: np.ndarray) -> np.ndarray:
        m = self.table.drop(self.indenter, dist_mm, 0.0, 0.0)
        return m if self.gain is None else m * self.gain[taxel]

    def height_mm(
        self, strength: np.ndarray, strength_err: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        s = np.asarray(strength, float)
        p, g = self.profile[::-1], self.gap_mm[::-1]  # increasing P for np.interp
        h = np.interp(s, p, g)
        beyond = s < self.profile[-1]
        last = max(float(self.profile[-1]), 1e-300)
        h = np.where(
            beyond,
            self.gap_mm[-1] + self.tail_decay_mm * np.log(last / np.maximum(s, 1e-300)),
            h,
        )
        h = np.where(s >= 1.0, 0.0, h)
        slope = np.gradient(self.profile, self.gap_mm)  # dP/dg (< 0)
        at = np.interp(h, self.gap_mm, slope)
        at = np.where(beyond, -np.maximum(s, 1e-300) / self.tail_decay_mm, at)
        with np.errstate(divide="ignore"):
            err = np.asarray(strength_err, float) / np.abs(at)
        return h, err


def crossing_heights(
    table: CrossingSkin,
    params: SkinParams,
    taxel_ids: np.ndarray | None = None,
    footprint: str | None = None,
    divided: bool = False,
) -> CrossingHeights:
    """The `CrossingHeights` of a crossing table with a `forward.SkinParams`' noise and
    measured gains (``taxel_gain``, for `taxel_ids`, unless the activations are already
    `divided` by them), for the indenter `heights.footprint_name` picks."""
    from fruitcli.sensing.skin.forward import load_taxel_gains
    from fruitcli.sensing.skin.heights import footprint_name

    noise = params.noise_std_counts
    noise = float(max(noise)) if isinstance(noise, tuple) else float(noise)
    gain = None
    if params.taxel_gain is not None and not divided and taxel_ids is not None:
        gain = load_taxel_gains(params.taxel_gain, taxel_ids)
    return CrossingHeights.of(table, footprint_name(params, footprint), noise, gain)
