"""The grounded objects that touch the skin: the bench's indenters and a finger.

Units: mm. Each is a solid of revolution about a vertical axis through (dx, dy), its
lowest point `gap` above the surface z = 0, reaching up through the top of the cell
(the rest of the object and the body holding it are far from the crossing). Each is a
grounded conductor (the printer's frame, the hand's body).

- ``small``: the rubber tip, a rod of radius 1.5 mm with a hemispherical end
  (`fruitcli.sensing.skin.forward.INDENTER_RADIUS_MM`; taken as conductive, as the bench's
  detections require);
- ``medium``: the Allen key, a flat-ended rod of radius 4 mm (the same table; its
  hexagon taken as the circle of that radius);
- ``finger``: a rounded cylinder of radius `FINGER_RADIUS_MM`, a fingertip pad about
  16 mm wide, pointing down.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FINGER_RADIUS_MM = 8.0
"""Radius of the finger's rounded cylinder (mm): an adult fingertip is about 16 mm wide."""

INSIDE_TOL_MM = 1e-6
"""A node this close to an object's surface belongs to the object."""


@dataclass(frozen=True)
class TouchObject:
    """A grounded rod of `radius_mm` with a hemispherical (`rounded`) or flat end."""

    name: str
    radius_mm: float
    rounded: bool

    def contains(self, points: np.ndarray, dx: float, dy: float, gap: float) -> np.ndarray:
        """(p,) True for points (p, 3) inside or on the object placed at (dx, dy, gap)."""
        rho = np.hypot(points[:, 0] - dx, points[:, 1] - dy)
        z = points[:, 2]
        r = self.radius_mm
        if not self.rounded:
            return (rho <= r + INSIDE_TOL_MM) & (z >= gap - INSIDE_TOL_MM)
        centre = gap + r
        in_rod = (rho <= r + INSIDE_TOL_MM) & (z >= centre)
        in_cap = np.hypot(rho, z - centre) <= r + INSIDE_TOL_MM
        return in_rod | in_cap


OBJECTS = {
    "small": TouchObject("small", 1.5, True),
    "medium": TouchObject("medium", 4.0, False),
    "finger": TouchObject("finger", FINGER_RADIUS_MM, True),
}
"""The objects of the crossing's table, by name."""
