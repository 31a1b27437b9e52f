"""Units inside the solver, stated once.

Lengths in mm, stresses and pressures in kPa (= mN/mm^2), forces in mN, so a
stiffness is in mN/mm, a volume in mm^3 and a cavity compliance in mm^3/kPa.
User-facing inputs are converted here and nowhere else:

- spring stiffness: N/mm -> mN/mm (x 1000);
- body force from density and gravity: kg/m^3 * m/s^2 = N/m^3 = 1e-9 N/mm^3
  = 1e-6 mN/mm^3.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

MN_PER_N = 1000.0
"""mN in one N."""

BODY_FORCE_MN_MM3_PER_KG_M3_M_S2 = 1e-6
"""(kg/m^3)(m/s^2) = N/m^3 = 1e-9 N/mm^3 = 1e-6 mN/mm^3."""


def spring_mn_per_mm(stiffness_n_per_mm: float) -> float:
    """Spring stiffness in the solver's unit (mN/mm) from N/mm."""
    return float(stiffness_n_per_mm) * MN_PER_N


def body_force_mn_mm3(density_kg_m3: float, gravity_m_s2: ArrayLike) -> np.ndarray:
    """Body force per volume (3,) in mN/mm^3 from density (kg/m^3) and gravity (m/s^2)."""
    return float(density_kg_m3) * np.asarray(gravity_m_s2, float) * BODY_FORCE_MN_MM3_PER_KG_M3_M_S2
