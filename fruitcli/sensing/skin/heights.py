"""How high above the surface a touch is, from how strong it is: the skin's height law.

Units: mm, counts.

A height model answers two questions (`HeightModel`): the activation a contact at a
point would give each taxel around it, and the height that a strength s (the measured
activation over that contact activation) means. `GapLaw` is the calibrated Gaussian
skin's (`fruitcli.sensing.skin.forward`, fitted by `fruit calibrate`):

    contact(d) = gain * contact_counts * exp(-d^2 / (2 sigma^2)),   s = exp(-h / gap_decay_mm)

so h = -gap_decay_mm ln s for s < 1 and 0 at and above contact (s >= 1: a firmer press).
Another model of the skin (an electrostatic one) plugs in by giving the same two
methods.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np

from fruitcli.errors import FrameError

if TYPE_CHECKING:
    from fruitcli.scene import SkinSection
    from fruitcli.sensing.skin.forward import SkinParams


class HeightModel(Protocol):
    """What touch shapes need from a skin model."""

    @property
    def noise_std_counts(self) -> float:
        """The skin's noise std (counts)."""

    @property
    def sigma_mm(self) -> float:
        """Footprint width of the touching object (mm)."""

    def contact_counts(self, taxel: np.ndarray, dist_mm: np.ndarray) -> np.ndarray:
        """Activation (counts) of taxels `taxel` at `dist_mm` from a contact point."""

    def height_mm(
        self, strength: np.ndarray, strength_err: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(height, its 1-sigma uncertainty) mm of strengths (n,) with their errors."""


@dataclass(frozen=True)
class GapLaw:
    """The Gaussian skin's height law (see the module docstring)."""

    contact: float  # counts at contact right under the indenter
    gap_decay_mm: float
    sigma_mm: float  # footprint width of the touching object
    noise_std_counts: float
    gain: np.ndarray | None = None  # (T,) taxel gains, None: 1 (or activations divided)
    height_as_distance: float = 1.0  # [skin].height_as_distance (forward's)
    height_as_gap: float = 0.0  # [skin].height_as_gap
    widening_per_mm: float = 0.0  # [skin].widening_per_mm

    def contact_counts(self, taxel: np.ndarray, dist_mm: np.ndarray) -> np.ndarray:
        m = self.contact * np.exp(-0.5 * (dist_mm / self.sigma_mm) ** 2)
        return m if self.gain is None else m * self.gain[taxel]

    def height_mm(
        self, strength: np.ndarray, strength_err: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        s = np.maximum(strength, 1e-12)
        h = np.maximum(-self.gap_decay_mm * np.log(s), 0.0)
        return h, self.gap_decay_mm * strength_err / s


def footprint_name(params: SkinParams, footprint: str | None) -> str:
    """The footprint heights assume: `footprint`, else the skin's only one, else small."""
    feet = params.footprint_sigma_mm
    if footprint is not None:
        if footprint not in feet:
            raise FrameError(
                f"[detection].footprint: expected one of {', '.join(feet)}, got {footprint!r}"
            )
        return footprint
    return next(iter(feet)) if len(feet) == 1 else "small"


def gap_law(
    params: SkinParams,
    taxel_ids: np.ndarray | None = None,
    footprint: str | None = None,
    divided: bool = False,
) -> GapLaw:
    """The `GapLaw` of a `forward.SkinParams`; its measured gains (``taxel_gain``) for
    `taxel_ids` unless the activations are already `divided` by them."""
    from fruitcli.sensing.skin.forward import load_taxel_gains

    noise = params.noise_std_counts
    noise = float(max(noise)) if isinstance(noise, tuple) else float(noise)
    gain = None
    if params.taxel_gain is not None and not divided and taxel_ids is not None:
        gain = load_taxel_gains(params.taxel_gain, taxel_ids)
    return GapLaw(
        params.contact_counts,
        params.gap_decay_mm,
        params.footprint_sigma_mm[footprint_name(params, footprint)],
        noise,
        gain,
        params.height_as_distance,
        params.height_as_gap,
        params.widening_per_mm,
    )


def skin_with_gap_law(path: str | Path) -> SkinSection:
    """The [skin] table of a skin file (`fruit calibrate`'s skin.toml) that must give
    heights: it has to state its gap law (gap_decay_mm, contact_counts)."""
    import tomllib

    from fruitcli.scene import load_skin_table

    table = load_skin_table(path)
    with open(path, "rb") as fh:
        given = tomllib.load(fh).get("skin", {})
    for key in ("gap_decay_mm", "contact_counts"):
        if key not in given:
            raise FrameError(
                f"{path}: [skin].{key}: missing; heights need the skin's gap law "
                "(fruit calibrate fits it from a bench descent)"
            )
    return table
