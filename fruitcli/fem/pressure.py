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


def volume_hessian_coo(x: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, ...]:
    """(rows, cols, values) of the volume Hessian d^2V/dx^2 (mm) in global dofs
    3 * node + component, duplicates to be summed. For V_t = x0.(x1 x x2)/6 the blocks
    are d^2V/dx_a dx_b = -[x_c]x / 6 for (a, b, c) cyclic, their transposes for (b, a),
    and zero on the diagonal; the pressure's load stiffness is -p times this."""
    p = x[tris]  # (t, 3, 3)
    t = len(tris)
    cross = np.zeros((t, 3, 3, 3))  # [x_c]x per vertex c
    cross[:, :, 0, 1], cross[:, :, 0, 2] = -p[:, :, 2], p[:, :, 1]
    cross[:, :, 1, 0], cross[:, :, 1, 2] = p[:, :, 2], -p[:, :, 0]
    cross[:, :, 2, 0], cross[:, :, 2, 1] = -p[:, :, 1], p[:, :, 0]
    rows, cols, vals = [], [], []
    for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        blk = -cross[:, c] / 6.0  # (t, 3, 3) d^2V / dx_a dx_b
        for (i, j, v) in ((a, b, blk), (b, a, np.transpose(blk, (0, 2, 1)))):
            r = 3 * tris[:, i, None, None] + np.arange(3)[None, :, None]
            cc = 3 * tris[:, j, None, None] + np.arange(3)[None, None, :]
            rows.append(np.broadcast_to(r, v.shape).ravel())
            cols.append(np.broadcast_to(cc, v.shape).ravel())
            vals.append(v.ravel())
    return np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
