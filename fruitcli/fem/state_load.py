"""The loads of one state (`Load`): each chamber's pressure or volume growth, and how much
of gravity, the jig's motion and the prescribed clamps act. Units: kPa, mm^3."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, TypeVar

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike


Mixed = TypeVar("Mixed", float, np.ndarray)
"""What `Load.lerp` mixes: a scale or an array of them."""


@dataclass(frozen=True)
class Load:
    """Loads of one state. Per chamber (K,): the pressure (kPa) or, where
    `volume_controlled`, the volume growth over the rest volume (mm^3). `gravity` and
    `jig` scale gravity and the jig's rotation/translation (0..1)."""

    pressure_kpa: np.ndarray = field(default_factory=lambda: np.zeros(0))
    volume_growth_mm3: np.ndarray = field(default_factory=lambda: np.zeros(0))
    volume_controlled: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    gravity: float = 1.0
    jig: float = 1.0
    prescribed: float = 1.0
    ratio: np.ndarray | None = None  # (K,): the chambers together, see `together`

    @classmethod
    def together(cls, ratio: ArrayLike, growth_mm3: float) -> Load:
        """The chambers inflated together along pressure ratios `ratio` (K,): their
        pressures are p_k = lambda ratio_k with one unknown lambda, the controlled
        volume sum_k ratio_k V_k grown by `growth_mm3` (spread over the chambers as
        ratio_k growth / |ratio|^2: only that weighted sum counts)."""
        r = np.asarray(ratio, float).reshape(-1)
        return cls(np.zeros(len(r)), r * growth_mm3 / float(r @ r), np.ones(len(r), bool), ratio=r)

    @classmethod
    def pressures(
        cls,
        pressure_kpa: ArrayLike,
        gravity: float = 1.0,
        jig: float = 1.0,
        prescribed: float = 1.0,
    ) -> Load:
        p = np.asarray(pressure_kpa, float).reshape(-1)
        return cls(p, np.zeros_like(p), np.zeros(len(p), bool), gravity, jig, prescribed)

    @classmethod
    def zero(cls, n_chambers: int, volume_controlled: ArrayLike | None = None) -> Load:
        vc = np.zeros(n_chambers, bool) if volume_controlled is None else volume_controlled
        return cls(np.zeros(n_chambers), np.zeros(n_chambers), np.asarray(vc, bool), 0.0, 0.0, 0.0)

    def is_zero(self) -> bool:
        """True when nothing loads the body (rest is then the exact answer)."""
        return not (
            np.any(self.pressure_kpa)
            or np.any(self.volume_growth_mm3)
            or self.gravity
            or self.jig
            or self.prescribed
        )

    def lerp(self, other: Load, t: float) -> Load:
        """The load a fraction t of the way from self to other."""

        def mix(a: Mixed, b: Mixed) -> Mixed:
            return (1.0 - t) * a + t * b

        return replace(
            other,
            pressure_kpa=mix(self.pressure_kpa, other.pressure_kpa),
            volume_growth_mm3=mix(self.volume_growth_mm3, other.volume_growth_mm3),
            gravity=mix(self.gravity, other.gravity),
            jig=mix(self.jig, other.jig),
            prescribed=mix(self.prescribed, other.prescribed),
        )
