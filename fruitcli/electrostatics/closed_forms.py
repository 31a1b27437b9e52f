"""Closed-form capacitances the field solver is checked against.

Units: mm, fF; `eps_r` is the relative permittivity (eps = eps0 * eps_r).
"""

from __future__ import annotations

import numpy as np

from fruitcli.electrostatics.assemble import EPS0_FF_PER_MM


def parallel_plate(area_mm2: float, gap_mm: float, eps_r: float = 1.0) -> float:
    """C = eps A / d (fF), the field uniform between the plates."""
    return EPS0_FF_PER_MM * eps_r * area_mm2 / gap_mm


def two_cylinders_per_length(
    radius_mm: float, centre_distance_mm: float, eps_r: float = 1.0
) -> float:
    """C' = pi eps / arccosh(D / 2a) (fF/mm) between two long parallel cylinders."""
    return np.pi * EPS0_FF_PER_MM * eps_r / np.arccosh(centre_distance_mm / (2 * radius_mm))


def cylinder_over_plane_per_length(radius_mm: float, height_mm: float, eps_r: float = 1.0) -> float:
    """C' = 2 pi eps / arccosh(h / a) (fF/mm): a cylinder, axis at h above a plane."""
    return 2 * np.pi * EPS0_FF_PER_MM * eps_r / np.arccosh(height_mm / radius_mm)


def sphere_over_plane(
    radius_mm: float, height_mm: float, eps_r: float = 1.0, terms: int = 2000
) -> float:
    """C = 4 pi eps R sinh(alpha) sum_{n>=1} 1 / sinh(n alpha), cosh(alpha) = h / R (fF):
    a sphere of radius R, centre at h > R above a grounded plane (the image series)."""
    alpha = np.arccosh(height_mm / radius_mm)
    x = np.arange(1, terms + 1) * alpha
    inv_sinh = 2.0 * np.exp(-x) / -np.expm1(-2.0 * x)  # 1 / sinh(x) without overflow
    return float(4 * np.pi * EPS0_FF_PER_MM * eps_r * radius_mm * np.sinh(alpha) * np.sum(inv_sinh))


def concentric_spheres(inner_mm: float, outer_mm: float, eps_r: float = 1.0) -> float:
    """C = 4 pi eps / (1/a - 1/b) (fF) between concentric spheres."""
    return 4 * np.pi * EPS0_FF_PER_MM * eps_r / (1.0 / inner_mm - 1.0 / outer_mm)


def image_factor(eps_r_source: float, eps_r_other: float) -> float:
    """(e1 - e2) / (e1 + e2): the image of a charge in medium e1 across a plane interface
    with medium e2 (charge at its mirror point, scaled by this)."""
    return (eps_r_source - eps_r_other) / (eps_r_source + eps_r_other)


def line_charge_over_dielectric(
    point_mm: np.ndarray,
    height_mm: float,
    eps_r_above: float,
    eps_r_below: float,
    charge_fc_per_mm: float = 1.0,
) -> np.ndarray:
    """Potential (V) at points (p, 2) = (x, z) of a line charge (fC/mm, along y) at
    (0, h) above the plane z = 0 between a medium eps_r_above (z > 0) and eps_r_below.

    Above: the charge and its image k q at (0, -h), k = image_factor(above, below), in
    eps_above; below: the charge scaled by 2 eps_below / (eps_above + eps_below) in
    eps_below. Defined up to a constant: the reference is the distance 1 mm."""
    p = np.asarray(point_mm, float)
    eps1, eps2 = EPS0_FF_PER_MM * eps_r_above, EPS0_FF_PER_MM * eps_r_below
    r_charge = np.hypot(p[:, 0], p[:, 1] - height_mm)
    r_image = np.hypot(p[:, 0], p[:, 1] + height_mm)
    k = image_factor(eps_r_above, eps_r_below)
    above = -charge_fc_per_mm / (2 * np.pi * eps1) * (np.log(r_charge) + k * np.log(r_image))
    t = 2 * eps2 / (eps1 + eps2)
    below = -t * charge_fc_per_mm / (2 * np.pi * eps2) * np.log(r_charge)
    return np.where(p[:, 1] >= 0, above, below)
