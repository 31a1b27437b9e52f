"""Corotational linear elasticity: per-tet rotation from the polar decomposition of the
deformation gradient (Irving-style SVD with a reflection fix where det F <= 0), the
internal force R K0 (R^T x - X) and the warped tangent R K0 R^T (SOFA's `large`/`polar`
tangent, without the dR/dx term).

Points (n, 3) mm, forces (n, 3) mN, stiffness blocks (m, 12, 12) mN/mm.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import scipy.sparse as sp


def deformation_gradients(x: np.ndarray, tets: np.ndarray, dm_inv: np.ndarray) -> np.ndarray:
    """(m, 3, 3) F = Ds Dm^-1 for current points x (n, 3) mm."""
    p = x[tets]
    ds = np.transpose(p[:, 1:] - p[:, :1], (0, 2, 1))
    return ds @ dm_inv


POLAR_ITERATIONS = 30
"""Cap of the scaled Newton iterations of the polar decomposition (they converge
quadratically; 6-9 suffice for stretches within a factor 10)."""

POLAR_TOLERANCE = 1e-13
"""Stop the polar iteration when no entry of R changes by more than this."""

POLAR_WARM_ITERATIONS = 4
"""Newton corrections of a warm-started rotation before the element falls back to the
cold polar iteration."""

POLAR_WARM_STOP = 1e-7
"""A warm-started element is done once its last rotation correction (radians) is below
this: the correction converges quadratically, so R is then exact to about 1e-14."""


def det3(a: np.ndarray) -> np.ndarray:
    """(m,) determinants of (m, 3, 3) matrices (closed form, faster than LAPACK here)."""
    return (
        a[:, 0, 0] * (a[:, 1, 1] * a[:, 2, 2] - a[:, 1, 2] * a[:, 2, 1])
        - a[:, 0, 1] * (a[:, 1, 0] * a[:, 2, 2] - a[:, 1, 2] * a[:, 2, 0])
        + a[:, 0, 2] * (a[:, 1, 0] * a[:, 2, 1] - a[:, 1, 1] * a[:, 2, 0])
    )


def polar_rotations(f: np.ndarray) -> np.ndarray:
    """(m, 3, 3) rotations R of F = R S from scratch (the solver warm-starts them in
    `kernels.kinematics` and sends here only the elements that fail there). Scaled
    Newton iteration R <- (g R + R^-T / g)/2 (Higham), all tets at once, with R^-T from
    cross products; where det F <= 0 the SVD is used and the column of the smallest
    singular value flipped so that R stays a proper rotation (Irving 2004)."""
    det = det3(f)
    bad = det <= 0.0
    r = f.copy()
    if bad.any():
        r[bad] = np.eye(3)
    for _ in range(POLAR_ITERATIONS):
        a, b, c = r[:, :, 0], r[:, :, 1], r[:, :, 2]
        cof = np.stack([_cross(b, c), _cross(c, a), _cross(a, b)], axis=2)
        d = np.einsum("mi,mi->m", a, cof[:, :, 0])
        g = np.abs(d) ** (-1.0 / 3.0)
        new = 0.5 * (g[:, None, None] * r + cof / (g * d)[:, None, None])
        change = np.abs(new - r).max()
        r = new
        if change < POLAR_TOLERANCE:
            break
    if bad.any():
        r[bad] = svd_rotations(f[bad])
    return r


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross products of (m, 3) arrays (np.cross is slow on many short rows)."""
    return np.stack(
        [
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ],
        axis=1,
    )


def svd_rotations(f: np.ndarray) -> np.ndarray:
    """(m, 3, 3) proper rotations U V^T from the SVD of F, flipping the column of the
    smallest singular value when det(U V^T) < 0 (inverted or flat tets)."""
    u, _, vt = np.linalg.svd(f)
    det = np.linalg.det(u @ vt)
    u[:, :, 2] *= np.where(det < 0.0, -1.0, 1.0)[:, None]
    return u @ vt


def forces_and_energy(
    x: np.ndarray,
    rest: np.ndarray,
    tets: np.ndarray,
    k0: np.ndarray,
    rot: np.ndarray,
    scatter: sp.csr_matrix | None = None,
) -> tuple[np.ndarray, float]:
    """Elastic forces (n, 3) mN and strain energy (mN mm = uJ) sum_e u.K0 u / 2 with
    u = R^T x_e - X_e. For isotropic Hooke and the polar R the forces are the exact
    gradient of this energy (the dR/dx term vanishes), so it serves the line search.
    `scatter` (optional, `scatter_matrix`) speeds up the sum into nodes."""
    m = len(tets)
    local = x[tets] @ rot - rest[tets]  # rows: (R^T x_a - X_a)^T, (m, 4, 3)
    g = (k0 @ local.reshape(m, 12, 1)).reshape(m, 4, 3)
    fe = g @ np.transpose(rot, (0, 2, 1))
    energy = 0.5 * float(np.einsum("mai,mai->", local, g))
    if scatter is not None:  # `scatter_matrix(tets, n)`: one sparse product
        return scatter @ fe.reshape(4 * m, 3), energy
    return scatter_nodes(tets, fe, len(x)), energy


def warped_stiffness(k0: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """(m, 12, 12) blocks R K0_ab R^T (mN/mm)."""
    m = len(k0)
    k = k0.reshape(m, 4, 3, 4, 3)
    k = np.einsum("mij,majbk->maibk", rot, k)
    k = np.einsum("maibk,mlk->maibl", k, rot)
    return k.reshape(m, 12, 12)


def scatter_nodes(tets: np.ndarray, values: np.ndarray, n_nodes: int) -> np.ndarray:
    """Sum per-element nodal vectors (m, 4, 3) into (n_nodes, 3)."""
    idx = tets.ravel()
    vals = values.reshape(-1, 3)
    return np.stack([np.bincount(idx, vals[:, c], minlength=n_nodes) for c in range(3)], axis=1)


def skew_stiffness(
    f: np.ndarray, rot: np.ndarray, lam: float, mu: float, project: bool = True
) -> np.ndarray:
    """(m, 3, 3) world-frame matrices T' = R T R^T of the rotation-derivative term.

    The corotational energy per unit rest volume is psi = mu |F - R|^2 + lam/2 tr(S - I)^2
    (S = R^T F), so P = 2 mu (F - R) + lam tr(S - I) R and, with dR = R [w]x from
    (tr S I - S) w = vee(R^T dF - dF^T R),
    dP = R C sym(R^T dF) + R [T a]x,  a = vee(skew(R^T dF)),
    T = 2 mu I + 2 c (tr S I - S)^-1,  c = lam tr(S - I) - 2 mu.
    The first part is SOFA's warped stiffness; the second acts only on the skew part of
    R^T dF (rotations) and is what the warped tangent misses. It is negative under
    compression; `project` clamps its eigenvalues at zero (Teran 2005), which makes each
    element's tangent positive semi-definite. The clamp is exact projection, because
    the two parts act on orthogonal subspaces (symmetric and skew). Without `project`
    the inverse is taken in closed form (no eigendecomposition) wherever tr S I - S is
    well conditioned; with `project`, also where Gershgorin's bound on the eigenvalues
    of tr S I - S shows that the clamp would change nothing (eigh only for the rest)."""
    from fruitcli.fem.materials import corotation_kernels as kernels

    f = np.ascontiguousarray(f, dtype=float)
    rot = np.ascontiguousarray(rot, dtype=float)
    t, easy = kernels.skew_stiffness_closed_form(f, rot, float(lam), float(mu), bool(project))
    hard = ~easy
    if hard.any():
        s = np.transpose(rot[hard], (0, 2, 1)) @ f[hard]  # R^T F
        s = 0.5 * (s + np.transpose(s, (0, 2, 1)))
        sig, u = np.linalg.eigh(s)
        trh = sig.sum(axis=1, keepdims=True)
        c = lam * (trh - 3.0) - 2.0 * mu
        q = trh - sig  # eigenvalues of tr S I - S
        with np.errstate(divide="ignore", invalid="ignore"):
            th = 2.0 * mu + 2.0 * c / q
        th = np.where(q > 1e-12, th, 0.0)
        if project:
            th = np.maximum(th, 0.0)
        ru = rot[hard] @ u
        t[hard] = (ru * th[:, None, :]) @ np.transpose(ru, (0, 2, 1))
    return t


def scatter_matrix(tets: np.ndarray, n_nodes: int) -> sp.csr_matrix:
    """Sparse (n_nodes, 4 m) sum of per-element nodal rows (m, 4, 3) -> (n_nodes, 3)."""
    import scipy.sparse as sp

    m = len(tets)
    return sp.csr_matrix((np.ones(4 * m), (tets.ravel(), np.arange(4 * m))), shape=(n_nodes, 4 * m))


def exact_stiffness(
    grads: np.ndarray,
    volumes: np.ndarray,
    lam: float,
    mu: float,
    rot: np.ndarray,
    f: np.ndarray,
    project: bool = True,
    warped_only: bool = False,
) -> np.ndarray:
    """(m, 12, 12) consistent tangent d f_int / dx (mN/mm) of the corotational forces:
    R K0 R^T plus the rotation-derivative term (see `skew_stiffness`), projected to
    positive semi-definite per element when `project`. With h_a = R g_a:
    R K0_ab R^T = V (lam h_a h_b^T + mu h_b h_a^T + mu (g_a . g_b) I) and the extra term
    (V / 2) [h_a]x^T T' [h_b]x."""
    m = len(grads)
    h = grads @ np.transpose(rot, (0, 2, 1))  # rows h_a = R g_a
    hf = h.reshape(m, 12)
    outer = hf[:, :, None] * hf[:, None, :]
    perm = outer.reshape(m, 4, 3, 4, 3).transpose(0, 3, 2, 1, 4).reshape(m, 12, 12)
    k = lam * outer + mu * perm
    gg = mu * (grads @ np.transpose(grads, (0, 2, 1)))  # (m, 4, 4)
    k = k.reshape(m, 4, 3, 4, 3)
    for i in range(3):
        k[:, :, i, :, i] += gg
    k = k.reshape(m, 12, 12)
    if not warped_only:
        t = skew_stiffness(f, rot, lam, mu, project)
        x4 = np.zeros((m, 3, 4, 3))  # [h_a]x side by side
        x4[:, 0, :, 1], x4[:, 0, :, 2] = -h[:, :, 2], h[:, :, 1]
        x4[:, 1, :, 0], x4[:, 1, :, 2] = h[:, :, 2], -h[:, :, 0]
        x4[:, 2, :, 0], x4[:, 2, :, 1] = -h[:, :, 1], h[:, :, 0]
        x = x4.reshape(m, 3, 12)
        k += 0.5 * (np.transpose(x, (0, 2, 1)) @ (t @ x))
    return k * volumes[:, None, None]
