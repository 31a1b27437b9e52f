"""Chamber pressure: cavity volume and its gradient H (the constraint row of the paper's
eq. 3, SoftRobots' SurfacePressureConstraint).

A chamber is a closed triangle surface (t, 3) oriented with normals pointing out of
the cavity (into the silicone), so its enclosed volume is positive. Pressure p (kPa)
on it pushes the nodes with the force p * H (mN), H = dV/dx (mm^2).
"""

from __future__ import annotations

import numpy as np


def cavity_volume(x: np.ndarray, tris: np.ndarray) -> float:
    """Enclosed volume (mm^3) of a closed, outward oriented surface: sum x0.(x1 x x2)/6."""
    p = x[tris]
    return float(np.einsum("ti,ti->", p[:, 0], np.cross(p[:, 1], p[:, 2])) / 6.0)


def volume_gradient(x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """(n, 3) H = dV/dx: each triangle adds its area vector / 3 to its 3 vertices (mm^2)."""
    p = x[tris]
    area_vec = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]) / 6.0  # (area normal / 2) / 3
    out = np.zeros_like(x)
    for c in range(3):
        out[:, c] = np.bincount(tris.ravel(), np.repeat(area_vec[:, c], 3), minlength=len(x))
    return out


def orient_outward(x: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Return `tris` flipped if needed so that the enclosed volume is positive."""
    tris = np.asarray(tris)
    return tris[:, [0, 2, 1]] if cavity_volume(x, tris) < 0.0 else tris
