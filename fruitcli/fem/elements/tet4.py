"""Linear tetrahedra: rest geometry, shape gradients and the Hooke element stiffness.

Points are (n, 3) float mm, tets (m, 4) int. Stiffness in mN/mm (E in kPa).
"""

from __future__ import annotations

import numpy as np


def lame_parameters(young_modulus_kpa: float, poisson_ratio: float) -> tuple[float, float]:
    """Lamé's (lambda, mu) in kPa from E (kPa) and nu."""
    e, nu = float(young_modulus_kpa), float(poisson_ratio)
    return e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), e / (2.0 * (1.0 + nu))


def edge_matrices(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(m, 3, 3) matrices whose columns are the edges x1-x0, x2-x0, x3-x0 (mm)."""
    p = points[tets]
    return np.transpose(p[:, 1:] - p[:, :1], (0, 2, 1))


def signed_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(m,) signed volumes (mm^3); positive for the right-handed node order."""
    return np.linalg.det(edge_matrices(points, tets)) / 6.0


def shape_gradients(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(m, 4, 3) gradients of the 4 linear shape functions (1/mm)."""
    dm_inv = np.linalg.inv(edge_matrices(points, tets))
    grads = np.empty((len(tets), 4, 3))
    grads[:, 1:] = dm_inv
    grads[:, 0] = -dm_inv.sum(axis=1)
    return grads


def element_stiffness(
    grads: np.ndarray, volumes_mm3: np.ndarray, lam_kpa: float, mu_kpa: float
) -> np.ndarray:
    """(m, 12, 12) small-strain Hooke stiffness V * B^T C B (mN/mm), dofs node-major.

    K[a i, b j] = V (lambda g_ai g_bj + mu g_aj g_bi + mu delta_ij g_a . g_b).
    """
    m = len(grads)
    v = volumes_mm3[:, None, None, None, None]
    k = lam_kpa * np.einsum("mai,mbj->maibj", grads, grads)
    k += mu_kpa * np.einsum("maj,mbi->maibj", grads, grads)
    gg = np.einsum("mak,mbk->mab", grads, grads)
    k += mu_kpa * np.einsum("mab,ij->maibj", gg, np.eye(3))
    return (v * k).reshape(m, 12, 12)


def tet_quality(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(m,) normalized volume quality 6 sqrt(2) V / l_rms^3: 1 regular, 0 flat, < 0 inverted."""
    p = points[tets]
    pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    sq = sum(((p[:, a] - p[:, b]) ** 2).sum(axis=1) for a, b in pairs) / 6.0
    l_rms = np.sqrt(np.maximum(sq, np.finfo(float).tiny))
    return 6.0 * np.sqrt(2.0) * signed_volumes(points, tets) / l_rms**3


def refuse_slivers(points: np.ndarray, tets: np.ndarray, min_quality: float) -> None:
    """MeshError naming the worst tet (m, 4) and where it is when its `tet_quality` is
    below `min_quality`."""
    from fruitcli.errors import MeshError

    quality = tet_quality(points, tets)
    worst = int(np.argmin(quality))
    if quality[worst] < min_quality:
        c = points[tets[worst]].mean(axis=0)
        raise MeshError(
            f"mesh: tet {worst} at ({c[0]:.2f}, {c[1]:.2f}, {c[2]:.2f}) mm is "
            f"a sliver (quality {quality[worst]:.2e} < {min_quality:g}); "
            "remesh before solving"
        )
