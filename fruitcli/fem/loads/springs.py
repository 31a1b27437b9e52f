"""Jig springs: nodes of a region pulled towards their rest position rotated by an angle
about an axis through a pivot, then translated (the paper's tip rotated 30 degrees).

Stiffness per node in mN/mm; positions mm; angles in degrees at the user edge.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike


def rotation_matrix(axis: ArrayLike, angle_deg: float) -> np.ndarray:
    """(3, 3) right-handed rotation by `angle_deg` about `axis` (Rodrigues)."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    t = np.deg2rad(angle_deg)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(t) * k + (1.0 - np.cos(t)) * (k @ k)


def nodes_in_box(points: np.ndarray, box_mm: ArrayLike) -> np.ndarray:
    """Indices of points inside [xmin, ymin, zmin, xmax, ymax, zmax] (bounds included)."""
    b = np.asarray(box_mm, float)
    inside = np.all((points >= b[:3]) & (points <= b[3:]), axis=1)
    return np.flatnonzero(inside)


@dataclass(frozen=True)
class Jig:
    """Springs on `nodes` towards R (X - pivot) + pivot + translate (mm)."""

    nodes: np.ndarray
    stiffness_mn_per_mm: float
    rotate_deg: float = 0.0
    axis: tuple = (0.0, 0.0, 1.0)
    pivot_mm: tuple = (0.0, 0.0, 0.0)
    translate_mm: tuple = (0.0, 0.0, 0.0)

    def targets(self, rest: np.ndarray, fraction: float = 1.0) -> np.ndarray:
        """(len(nodes), 3) spring anchors with the rotation and translation scaled by
        `fraction` (load stepping from the rest position)."""
        rot = rotation_matrix(self.axis, fraction * self.rotate_deg)
        piv = np.asarray(self.pivot_mm, float)
        x = rest[self.nodes] - piv
        return x @ rot.T + piv + fraction * np.asarray(self.translate_mm, float)
