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


def nearest_on_surface(
    obj: TouchObject, points: np.ndarray, dx: float, dy: float, gap: float
) -> tuple[np.ndarray, np.ndarray]:
    """(signed distance (p,) mm, nearest surface point (p, 3)) of points (p, 3) to
    `obj` with its tip at (dx, dy, gap): negative inside. The rod is taken as endless
    upwards (the cell's top cuts it)."""
    rel = points - np.array([dx, dy, 0.0])
    rho = np.hypot(rel[:, 0], rel[:, 1])
    safe = np.where(rho > 0, rho, 1.0)
    ux, uy = rel[:, 0] / safe, rel[:, 1] / safe  # radial direction (any at the axis)
    ux = np.where(rho > 0, ux, 1.0)
    r, z = obj.radius_mm, points[:, 2]
    near = points.copy()
    if obj.rounded:
        centre = gap + r
        below = z < centre
        cap = np.stack([rel[:, 0], rel[:, 1], z - centre], axis=1)
        dist_c = np.linalg.norm(cap, axis=1)
        scale = r / np.where(dist_c > 0, dist_c, 1.0)
        cap_pt = np.array([dx, dy, centre]) + cap * scale[:, None]
        cap_pt[dist_c == 0] = [dx, dy, gap]
        side = np.stack([dx + r * ux, dy + r * uy, z], axis=1)
        near = np.where(below[:, None], cap_pt, side)
        signed = np.where(below, dist_c - r, rho - r)
        return signed, near
    out_r, out_z = rho - r, gap - z  # > 0: outside across the side, under the end
    corner = (out_r > 0) & (out_z > 0)
    signed = np.where(corner, np.hypot(out_r, out_z), np.maximum(out_r, out_z))
    to_side = corner | (out_r >= out_z)
    to_end = corner | (out_r < out_z)
    near[:, 0] = np.where(to_side, dx + r * ux, points[:, 0])
    near[:, 1] = np.where(to_side, dy + r * uy, points[:, 1])
    near[:, 2] = np.where(to_end, gap, z)
    return signed, near
