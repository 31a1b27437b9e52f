"""Corotational linear elasticity: per-tet rotation from the polar decomposition of the
deformation gradient (Irving-style SVD with a reflection fix where det F <= 0), the
internal force R K0 (R^T x - X) and the warped tangent R K0 R^T (SOFA's `large`/`polar`
tangent, without the dR/dx term).

Points (n, 3) mm, forces (n, 3) mN, stiffness blocks (m, 12, 12) mN/mm.
"""

from __future__ import annotations

import numpy as np


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
    return (a[:, 0, 0] * (a[:, 1, 1] * a[:, 2, 2] - a[:, 1, 2] * a[:, 2, 1])
            - a[:, 0, 1] * (a[:, 1, 0] * a[:, 2, 2] - a[:, 1, 2] * a[:, 2, 0])
            + a[:, 0, 2] * (a[:, 1, 0] * a[:, 2, 1] - a[:, 1, 1] * a[:, 2, 0]))


def adjugate3(a: np.ndarray) -> np.ndarray:
    """(m, 3, 3) adjugates (transposed cofactors): a @ adj(a) = det(a) I."""
    cof = np.empty_like(a)
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            cof[:, j, i] = a[:, i1, j1] * a[:, i2, j2] - a[:, i1, j2] * a[:, i2, j1]
    return cof


def _cross_matrix(w: np.ndarray) -> np.ndarray:
    """(m, 3, 3) [w]x with [w]x v = w x v."""
    z = np.zeros(len(w))
    return np.stack([np.stack([z, -w[:, 2], w[:, 1]], 1),
                     np.stack([w[:, 2], z, -w[:, 0]], 1),
                     np.stack([-w[:, 1], w[:, 0], z], 1)], 1)


def polar_rotations(f: np.ndarray, guess: np.ndarray | None = None) -> np.ndarray:
    """(m, 3, 3) rotations R of F = R S. Scaled Newton iteration R <- (g R + R^-T / g)/2
    (Higham), all tets at once, with R^-T from cross products; where det F <= 0 the SVD
    is used and the column of the smallest singular value flipped so that R stays a
    proper rotation (Irving 2004).

    With `guess` (rotations of a nearby configuration), R is corrected instead by
    Newton on skew(R^T F) = 0: (tr S I - S) w = vee(A - A^T), A = R^T F, S = sym(A),
    R <- R cay(w) (Cayley), at most POLAR_WARM_ITERATIONS times; elements that do not
    converge, or whose tr S I - S is not positive definite, take the cold path. The
    warm path works on (3, 3, m) arrays, where numpy's batched 3x3 products are fast."""
    if guess is None or len(guess) != len(f):
        return _polar_cold(f)
    fc = np.ascontiguousarray(np.transpose(f, (1, 2, 0)))  # (3, 3, m): fast batched 3x3
    r = np.ascontiguousarray(np.transpose(guess, (1, 2, 0)))
    m = len(f)
    idx = np.arange(m)  # elements still iterating; after the first corrections only
    bad = np.zeros(m, bool)  # the few that need another are worked on (cold path: bad)
    for _ in range(POLAR_WARM_ITERATIONS):
        whole = len(idx) == m
        # np.take keeps (3, 3, k) C-contiguous (r[:, :, idx] would put k first in memory)
        rs, fs = (r, fc) if whole else (np.take(r, idx, 2), np.take(fc, idx, 2))
        w, ok = _warm_correction(rs, fs)
        rs = _rotate_cayley(rs, w)
        if whole:
            r = rs
        else:
            r[:, :, idx] = rs
        bad[idx[~ok]] = True
        idx = idx[ok & (np.abs(w).max(axis=0) > POLAR_WARM_STOP)]
        if not len(idx):
            break
    todo = np.flatnonzero(bad)
    if len(idx):
        todo = np.union1d(todo, idx)
    out = np.ascontiguousarray(np.transpose(r, (2, 0, 1)))
    if len(todo):
        out[todo] = _polar_cold(f[todo])
    return out


def _warm_correction(r: np.ndarray, fc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One Newton correction w (3, m) of the rotations r (3, 3, m) towards the polar
    rotation of fc: (tr S I - S) w = vee(A - A^T), A = R^T F, S = sym(A) (adjugate of the
    symmetric 3x3 in closed form), and where tr S I - S is positive definite (ok)."""
    a = np.einsum("jim,jkm->ikm", r, fc)  # R^T F
    tr = a[0, 0] + a[1, 1] + a[2, 2]
    q00, q11, q22 = tr - a[0, 0], tr - a[1, 1], tr - a[2, 2]
    q01 = -0.5 * (a[0, 1] + a[1, 0])
    q02 = -0.5 * (a[0, 2] + a[2, 0])
    q12 = -0.5 * (a[1, 2] + a[2, 1])
    c00 = q11 * q22 - q12 * q12
    c11 = q00 * q22 - q02 * q02
    c22 = q00 * q11 - q01 * q01
    c01 = q02 * q12 - q01 * q22
    c02 = q01 * q12 - q02 * q11
    c12 = q01 * q02 - q00 * q12
    det_q = q00 * c00 + q01 * c01 + q02 * c02
    ok = (det_q > 1e-9 * np.abs(tr) ** 3) & (q00 > 0) & (tr > 0)
    b0, b1, b2 = a[2, 1] - a[1, 2], a[0, 2] - a[2, 0], a[1, 0] - a[0, 1]
    s = np.where(ok, 1.0 / np.where(ok, det_q, 1.0), 0.0)
    w = np.empty((3, len(tr)))
    np.multiply(c00 * b0 + c01 * b1 + c02 * b2, s, out=w[0])
    np.multiply(c01 * b0 + c11 * b1 + c12 * b2, s, out=w[1])
    np.multiply(c02 * b0 + c12 * b1 + c22 * b2, s, out=w[2])
    return w, ok


def _rotate_cayley(r: np.ndarray, w: np.ndarray) -> np.ndarray:
    """r cay(w / 2) for rotations r (3, 3, m): cay(u) = I + k ([u]x + u u^T - |u|^2 I),
    k = 2 / (1 + |u|^2)."""
    u0, u1, u2 = 0.5 * w
    uu = u0 * u0 + u1 * u1 + u2 * u2
    k = 2.0 / (1.0 + uu)
    d = 1.0 - k * uu
    ku0, ku1, ku2 = k * u0, k * u1, k * u2
    cay = np.empty((3, 3, len(uu)))
    cay[0, 0] = d + ku0 * u0
    cay[1, 1] = d + ku1 * u1
    cay[2, 2] = d + ku2 * u2
    a01, a02, a12 = ku0 * u1, ku0 * u2, ku1 * u2
    cay[0, 1] = a01 - ku2
    cay[1, 0] = a01 + ku2
    cay[0, 2] = a02 + ku1
    cay[2, 0] = a02 - ku1
    cay[1, 2] = a12 - ku0
    cay[2, 1] = a12 + ku0
    return np.einsum("ijm,jkm->ikm", r, cay)


def _polar_cold(f: np.ndarray) -> np.ndarray:
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
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                     a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def svd_rotations(f: np.ndarray) -> np.ndarray:
    """(m, 3, 3) proper rotations U V^T from the SVD of F, flipping the column of the
    smallest singular value when det(U V^T) < 0 (inverted or flat tets)."""
    u, _, vt = np.linalg.svd(f)
    det = np.linalg.det(u @ vt)
    u[:, :, 2] *= np.where(det < 0.0, -1.0, 1.0)[:, None]
    return u @ vt


def internal_forces(x: np.ndarray, rest: np.ndarray, tets: np.ndarray, k0: np.ndarray,
                    rot: np.ndarray) -> np.ndarray:
    """(n, 3) elastic forces (mN) that resist the deformation: sum_e R K0 (R^T x_e - X_e)."""
    return forces_and_energy(x, rest, tets, k0, rot)[0]


def forces_and_energy(x: np.ndarray, rest: np.ndarray, tets: np.ndarray, k0: np.ndarray,
                      rot: np.ndarray, scatter=None) -> tuple[np.ndarray, float]:
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


def apply_warped(k0: np.ndarray, rot: np.ndarray, tets: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Matrix-free product (sum_e R K0 R^T) v for v (n, 3); returns (n, 3)."""
    m = len(tets)
    local = v[tets] @ rot
    g = (k0 @ local.reshape(m, 12, 1)).reshape(m, 4, 3)
    fe = g @ np.transpose(rot, (0, 2, 1))
    return scatter_nodes(tets, fe, len(v))


def scatter_nodes(tets: np.ndarray, values: np.ndarray, n_nodes: int) -> np.ndarray:
    """Sum per-element nodal vectors (m, 4, 3) into (n_nodes, 3)."""
    idx = tets.ravel()
    vals = values.reshape(-1, 3)
    return np.stack([np.bincount(idx, vals[:, c], minlength=n_nodes) for c in range(3)], axis=1)


def skew_stiffness(f: np.ndarray, rot: np.ndarray, lam: float, mu: float,
                   project: bool = True) -> np.ndarray:
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
    t = np.zeros((3, 3, len(f)))
    rc, fc = soa(rot), soa(f)
    s = np.einsum("kim,kjm->ijm", rc, fc)  # R^T F
    s = 0.5 * (s + np.transpose(s, (1, 0, 2)))
    tr = s[0, 0] + s[1, 1] + s[2, 2]
    c = lam * (tr - 3.0) - 2.0 * mu
    q = -s
    for i in range(3):
        q[i, i] += tr
    adj = np.empty_like(q)
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            adj[j, i] = q[i1, j1] * q[i2, j2] - q[i1, j2] * q[i2, j1]
    det_q = q[0, 0] * adj[0, 0] + q[0, 1] * adj[1, 0] + q[0, 2] * adj[2, 0]
    easy = det_q > 1e-6 * np.abs(tr) ** 3
    if project:  # the clamp is idle where Gershgorin bounds every 2 mu + 2 c / q_i >= 0
        q_low = np.min([q[i, i] - np.abs(q[i, (i + 1) % 3]) - np.abs(q[i, (i + 2) % 3])
                        for i in range(3)], axis=0)  # <= smallest eigenvalue
        easy &= (q_low > 0.0) & ((c >= 0.0) | (mu * q_low + c >= 0.0))
    if easy.any():
        te = adj * np.where(easy, 2.0 * c / np.where(easy, det_q, 1.0), 0.0)
        for i in range(3):
            te[i, i] += np.where(easy, 2.0 * mu, 0.0)
        t = _mmt(_mm(rc, te), rc)
    t = np.transpose(t, (2, 0, 1))
    s = np.transpose(s, (2, 0, 1))
    hard = ~easy
    if hard.any():
        sig, u = np.linalg.eigh(s[hard])
        trh = sig.sum(axis=1, keepdims=True)
        q = trh - sig  # eigenvalues of tr S I - S
        with np.errstate(divide="ignore", invalid="ignore"):
            th = 2.0 * mu + 2.0 * c[hard, None] / q
        th = np.where(q > 1e-12, th, 0.0)
        if project:
            th = np.maximum(th, 0.0)
        ru = rot[hard] @ u
        t[hard] = (ru * th[:, None, :]) @ np.transpose(ru, (0, 2, 1))
    return t


def apply_tangent(grads: np.ndarray, volumes: np.ndarray, lam: float, mu: float,
                  rot: np.ndarray, t_world: np.ndarray | None, tets: np.ndarray,
                  v: np.ndarray, scatter, h: np.ndarray | None = None) -> np.ndarray:
    """Matrix-free product of the consistent tangent (see `exact_stiffness`) with v
    (n, 3); t_world from `skew_stiffness` (None: the warped tangent). Per element, with
    h_a = R g_a and G = sum_b v_b h_b^T: (K v)_a = M h_a, M = V (lam tr G I + mu (G +
    G^T)) + [V T' w / 2]x, w = sum_b h_b x v_b. `h` (m, 4, 3): the rows h_a, when the
    caller keeps them across products. Returns (n, 3)."""
    m = len(tets)
    if h is None:
        h = rotated_gradients(grads, rot)
    g = np.transpose(v[tets], (0, 2, 1)) @ h  # (m, 3, 3) sum_b v_b h_b^T
    mm = mu * (g + np.transpose(g, (0, 2, 1)))
    mm[:, [0, 1, 2], [0, 1, 2]] += (lam * (g[:, 0, 0] + g[:, 1, 1] + g[:, 2, 2]))[:, None]
    if t_world is not None:
        w = np.stack([g[:, 2, 1] - g[:, 1, 2], g[:, 0, 2] - g[:, 2, 0],
                      g[:, 1, 0] - g[:, 0, 1]], axis=1)
        mm += 0.5 * _cross_matrix((t_world @ w[:, :, None])[:, :, 0])
    mm *= volumes[:, None, None]
    fe = h @ np.transpose(mm, (0, 2, 1))  # rows (M h_a)^T
    return scatter @ fe.reshape(4 * m, 3)


def rotated_gradients(grads: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """(m, 4, 3) rows h_a = R g_a of the rotated rest shape-function gradients."""
    return grads @ np.transpose(rot, (0, 2, 1))


def scatter_matrix(tets: np.ndarray, n_nodes: int):
    """Sparse (n_nodes, 4 m) sum of per-element nodal rows (m, 4, 3) -> (n_nodes, 3)."""
    import scipy.sparse as sp

    m = len(tets)
    return sp.csr_matrix((np.ones(4 * m), (tets.ravel(), np.arange(4 * m))),
                         shape=(n_nodes, 4 * m))


def exact_stiffness(grads: np.ndarray, volumes: np.ndarray, lam: float, mu: float,
                    rot: np.ndarray, f: np.ndarray, project: bool = True,
                    warped_only: bool = False) -> np.ndarray:
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
        x = np.zeros((m, 3, 4, 3))  # [h_a]x side by side
        x[:, 0, :, 1], x[:, 0, :, 2] = -h[:, :, 2], h[:, :, 1]
        x[:, 1, :, 0], x[:, 1, :, 2] = h[:, :, 2], -h[:, :, 0]
        x[:, 2, :, 0], x[:, 2, :, 1] = -h[:, :, 1], h[:, :, 0]
        x = x.reshape(m, 3, 12)
        k += 0.5 * (np.transpose(x, (0, 2, 1)) @ (t @ x))
    return k * volumes[:, None, None]


class GradientOperator:
    """The rest shape-function gradients as one sparse operator over all elements, for
    the per-iteration kernels in component-major (3, 3, m) arrays (contiguous per entry,
    where numpy's elementwise work is fast): `grad(v)` = sum_b v_b g_b^T per element
    (the deformation gradient F for v = x), and its adjoint `div(n)`, the nodal sums
    sum_e n_e g_a. With them the corotational forces are div(V R sigma(R^T F - I)) and
    the consistent tangent product is div(M R) (see `apply_tangent`)."""

    def __init__(self, grads: np.ndarray, tets: np.ndarray, n_nodes: int):
        import scipy.sparse as sp

        m = len(tets)
        # row (3 i + j) m + e, column 3 tets[e, b] + i, value g_bj
        i, j, e, b = np.meshgrid(np.arange(3), np.arange(3), np.arange(m), np.arange(4),
                                 indexing="ij")
        rows = ((3 * i + j) * m + e).ravel()
        cols = (3 * tets[e, b] + i).ravel()
        vals = grads[e, b, j].ravel()
        self.m = m
        self.b = sp.csr_matrix((vals, (rows, cols)), shape=(9 * m, 3 * n_nodes))
        self.bt = self.b.T.tocsr()

    def grad(self, v: np.ndarray) -> np.ndarray:
        """(3, 3, m) sum_b v_b g_b^T for nodal vectors v (n, 3)."""
        return (self.b @ v.reshape(-1)).reshape(3, 3, self.m)

    def div(self, n: np.ndarray) -> np.ndarray:
        """(n, 3) sum over elements of n_e g_a into node a, for n (3, 3, m)."""
        return (self.bt @ n.reshape(-1)).reshape(-1, 3)


def soa(a: np.ndarray) -> np.ndarray:
    """(3, 3, m) contiguous copy of (m, 3, 3) matrices (or a view when a is one)."""
    return np.ascontiguousarray(np.transpose(a, (1, 2, 0)))


def _mm(a: np.ndarray, b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """(3, 3, m) products a_e b_e."""
    return np.einsum("ikm,kjm->ijm", a, b, out=out)


def _mmt(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3, 3, m) products a_e b_e^T."""
    return np.einsum("ikm,jkm->ijm", a, b)


def forces_and_energy_soa(op: GradientOperator, volumes: np.ndarray, lam: float, mu: float,
                          f: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, float]:
    """`forces_and_energy` from F and R as (3, 3, m) arrays: with H = R^T F - I and
    sigma = lam tr H I + mu (H + H^T), the forces are div(V R sigma) and the energy
    sum V sigma : H / 2 (equal to R K0 (R^T x - X) of the isotropic Hooke K0)."""
    h = np.einsum("kim,kjm->ijm", rot, f)  # R^T F
    tr = h[0, 0] + h[1, 1] + h[2, 2] - 3.0
    sig = mu * (h + np.transpose(h, (1, 0, 2)))
    for i in range(3):
        sig[i, i] += lam * tr - 2.0 * mu
        h[i, i] -= 1.0
    sig *= volumes
    energy = 0.5 * float(np.einsum("ijm,ijm->", sig, h))
    return op.div(_mm(rot, sig)), energy


def apply_tangent_soa(op: GradientOperator, volumes: np.ndarray, lam: float, mu: float,
                      rot: np.ndarray, t_world: np.ndarray | None, v: np.ndarray) -> np.ndarray:
    """`apply_tangent` with R and T' as (3, 3, m) arrays: G = grad(v) R^T, M as there,
    K v = div(M R). Returns (n, 3)."""
    g = _mmt(op.grad(v), rot)
    mm = mu * (g + np.transpose(g, (1, 0, 2)))
    tr = lam * (g[0, 0] + g[1, 1] + g[2, 2])
    for i in range(3):
        mm[i, i] += tr
    if t_world is not None:
        w = np.stack([g[2, 1] - g[1, 2], g[0, 2] - g[2, 0], g[1, 0] - g[0, 1]])
        tw = 0.5 * np.einsum("ijm,jm->im", t_world, w)
        mm[0, 1] -= tw[2]
        mm[0, 2] += tw[1]
        mm[1, 0] += tw[2]
        mm[1, 2] -= tw[0]
        mm[2, 0] -= tw[1]
        mm[2, 1] += tw[0]
    mm *= volumes
    return op.div(_mm(mm, rot))
