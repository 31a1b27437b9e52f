"""Compiled per-element loops (numba) for the kernels a Newton step repeats: the
kinematics (F, warm-started polar rotation, det F), the corotational forces with their
strain energy, the rotation-derivative term of the consistent tangent, and the tangent
applied to a vector (CG's product).
One pass over the elements each, without the temporaries numpy would allocate: about
2x faster than the vectorized versions on the default fruit. They release the GIL, so
the online FEM thread of `fruit live --online` does not hold up the detection loop.

The element loops run over every core, their nodal sums gathered in element order
(`fruitcli.fem.element_sums`): the same bits whatever the number of threads.

Arrays are element-major: tets (m, 4), grads (m, 4, 3) rest shape-function gradients
(1/mm), volumes (m,) mm^3, F and R (m, 3, 3), nodal vectors (n, 3). Lame parameters and
stresses in kPa, forces in mN, energy in mN mm. Compiled (or loaded from numba's disk
cache) by `warm_up` when a `Model` is built.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from fruitcli.fem.element_sums import block_range, gather_rows, n_blocks, node_incidence


@njit(cache=True, nogil=True, inline="always")
def _rt_f(r, f, out):
    """out = R^T F for 3 x 3 R and F."""
    for i in range(3):
        for j in range(3):
            out[i, j] = r[0, i] * f[0, j] + r[1, i] * f[1, j] + r[2, i] * f[2, j]


@njit(cache=True, nogil=True, parallel=True)
def kinematics(
    x, tets, grads, guess, use_guess, iterations, stop
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(f, rot, det, cold) at points x (n, 3): F = sum_b x_b g_b^T, det F, and R of F = R S
    by Newton on skew(R^T F) = 0 from the rotations `guess` (m, 3, 3) of a nearby
    configuration: (tr S I - S) w = vee(A - A^T), A = R^T F, S = sym(A), R <- R cay(w/2),
    at most `iterations` times, done once |w| <= stop (radians). `cold` (m,) marks the
    elements left to the caller's cold polar decomposition: all without `use_guess`, else
    the inverted or flat ones (det F <= 0), those where tr S I - S is not positive
    definite and those that did not converge."""
    m = tets.shape[0]
    f = np.empty((m, 3, 3))
    rot = np.empty((m, 3, 3))
    det = np.empty(m)
    cold = np.zeros(m, dtype=np.bool_)
    nblocks = n_blocks(m)
    for blk in prange(nblocks):
        a = np.empty((3, 3))
        r = np.empty((3, 3))
        c = np.empty((3, 3))
        lo, hi = block_range(blk, nblocks, m)
        for e in range(lo, hi):
            for i in range(3):
                for j in range(3):
                    s = 0.0
                    for b in range(4):
                        s += x[tets[e, b], i] * grads[e, b, j]
                    f[e, i, j] = s
            fe = f[e]
            det[e] = (
                fe[0, 0] * (fe[1, 1] * fe[2, 2] - fe[1, 2] * fe[2, 1])
                - fe[0, 1] * (fe[1, 0] * fe[2, 2] - fe[1, 2] * fe[2, 0])
                + fe[0, 2] * (fe[1, 0] * fe[2, 1] - fe[1, 1] * fe[2, 0])
            )
            if not use_guess or det[e] <= 0.0:  # inverted or flat: the cold path's SVD
                cold[e] = True
                continue
            r[:, :] = guess[e]
            done = False
            for _ in range(iterations):
                _rt_f(r, fe, a)
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
                # tr S I - S positive definite (Sylvester: leading minors q00, c22, det_q)
                if not (det_q > 1e-9 * abs(tr) ** 3 and q00 > 0.0 and c22 > 0.0 and tr > 0.0):
                    break
                b0, b1, b2 = a[2, 1] - a[1, 2], a[0, 2] - a[2, 0], a[1, 0] - a[0, 1]
                u0 = 0.5 * (c00 * b0 + c01 * b1 + c02 * b2) / det_q
                u1 = 0.5 * (c01 * b0 + c11 * b1 + c12 * b2) / det_q
                u2 = 0.5 * (c02 * b0 + c12 * b1 + c22 * b2) / det_q
                # cay(u) = I + k ([u]x + u u^T - |u|^2 I), k = 2 / (1 + |u|^2)
                uu = u0 * u0 + u1 * u1 + u2 * u2
                k = 2.0 / (1.0 + uu)
                d = 1.0 - k * uu
                c[0, 0], c[1, 1], c[2, 2] = d + k * u0 * u0, d + k * u1 * u1, d + k * u2 * u2
                c[0, 1], c[1, 0] = k * (u0 * u1 - u2), k * (u0 * u1 + u2)
                c[0, 2], c[2, 0] = k * (u0 * u2 + u1), k * (u0 * u2 - u1)
                c[1, 2], c[2, 1] = k * (u1 * u2 - u0), k * (u1 * u2 + u0)
                for i in range(3):
                    r0, r1, r2 = r[i, 0], r[i, 1], r[i, 2]
                    for j in range(3):
                        r[i, j] = r0 * c[0, j] + r1 * c[1, j] + r2 * c[2, j]
                if 2.0 * max(abs(u0), abs(u1), abs(u2)) <= stop:
                    done = True
                    break
            rot[e] = r
            cold[e] = not done
    return f, rot, det, cold


@njit(cache=True, nogil=True, parallel=True)
def forces_and_energy(tets, grads, volumes, lam, mu, f, rot, ptr, rows) -> tuple[np.ndarray, float]:
    """Elastic forces (n, 3) mN and strain energy (mN mm): with H = R^T F - I and
    sigma = lam tr H I + mu (H + H^T), node a of element e gets V R sigma g_a and the
    energy sums V sigma : H / 2 (R K0 (R^T x - X) of the isotropic Hooke K0). ptr, rows:
    `node_incidence` (the nodes' sums in element order)."""
    m = tets.shape[0]
    fe_rows = np.empty((4 * m, 3))
    energies = np.empty(m)
    nblocks = n_blocks(m)
    for blk in prange(nblocks):
        h = np.empty((3, 3))
        sig = np.empty((3, 3))
        p = np.empty((3, 3))
        lo, hi = block_range(blk, nblocks, m)
        for e in range(lo, hi):
            r = rot[e]
            _rt_f(r, f[e], h)
            for i in range(3):
                h[i, i] -= 1.0
            tr = lam * (h[0, 0] + h[1, 1] + h[2, 2])
            en = 0.0
            for i in range(3):
                for j in range(3):
                    sig[i, j] = mu * (h[i, j] + h[j, i])
                sig[i, i] += tr
                for j in range(3):
                    en += sig[i, j] * h[i, j]
            v = volumes[e]
            for i in range(3):
                for j in range(3):
                    p[i, j] = v * (r[i, 0] * sig[0, j] + r[i, 1] * sig[1, j] + r[i, 2] * sig[2, j])
            energies[e] = 0.5 * v * en
            for b in range(4):
                for i in range(3):
                    fe_rows[4 * e + b, i] = (
                        p[i, 0] * grads[e, b, 0]
                        + p[i, 1] * grads[e, b, 1]
                        + p[i, 2] * grads[e, b, 2]
                    )
    out = np.empty((ptr.shape[0] - 1, 3))
    gather_rows(fe_rows, ptr, rows, out)
    energy = 0.0
    for e in range(m):
        energy += energies[e]
    return out, energy


def tangent_product(
    tets: np.ndarray,
    grads: np.ndarray,
    volumes: np.ndarray,
    lam: float,
    mu: float,
    rot: np.ndarray,
    t_world: np.ndarray,
    with_t: bool,
    v: np.ndarray,
) -> np.ndarray:
    """Consistent tangent times v (n, 3) (mN) over every dof (`tangent_product_dofs`)."""
    n = v.shape[0]
    dof = np.arange(3 * n).reshape(n, 3)
    ptr, rows = node_incidence(tets, n)
    out = tangent_product_dofs(
        tets,
        rotated_gradients(grads, rot),
        volumes,
        lam,
        mu,
        t_world,
        with_t,
        dof,
        np.ascontiguousarray(v).reshape(-1),
        3 * n,
        ptr,
        rows,
    )
    return out.reshape(n, 3)


@njit(cache=True, nogil=True, parallel=True)
def rotated_gradients(grads: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """(m, 4, 3) R g_b: each element's shape-function gradients turned by its rotation
    (computed once per tangent, read by every product)."""
    m = grads.shape[0]
    rg = np.empty((m, 4, 3))
    for e in prange(m):
        r = rot[e]
        for b in range(4):
            for i in range(3):
                rg[e, b, i] = (
                    r[i, 0] * grads[e, b, 0] + r[i, 1] * grads[e, b, 1] + r[i, 2] * grads[e, b, 2]
                )
    return rg


@njit(cache=True, nogil=True, parallel=True)
def tangent_product_dofs(
    tets, rg, volumes, lam, mu, t_world, with_t, dof, v, n_out, ptr, rows
) -> np.ndarray:
    """Consistent tangent times v (mN), over the dofs numbered by dof (n, 3) (-1: held,
    its component of v is zero and its row dropped), v (n_out,): per element, with
    the rotated gradients rg = R g_b (`rotated_gradients`),
    G = sum_b v_b (R g_b)^T (= (sum_b v_b g_b^T) R^T),
    M = V (lam tr G I + mu (G + G^T) + [T' w / 2]x), w = vee(G - G^T), and node a gets
    M R g_a. t_world (m, 3, 3): the rotation-derivative term T' of
    `corotation.skew_stiffness`, used when `with_t` (else SOFA's warped R K0 R^T).
    Gathers and scatters through dof directly (CG's product over the free dofs without
    the full-size copies); ptr, rows: `node_incidence`."""
    m = tets.shape[0]
    e_rows = np.empty((4 * m, 3))
    nblocks = n_blocks(m)
    for blk in prange(nblocks):
        g = np.empty((3, 3))
        mm = np.empty((3, 3))
        ve = np.empty((4, 3))
        lo, hi = block_range(blk, nblocks, m)
        for e in range(lo, hi):
            for b in range(4):
                for i in range(3):
                    k = dof[tets[e, b], i]
                    ve[b, i] = v[k] if k >= 0 else 0.0
            for i in range(3):
                for j in range(3):
                    g[i, j] = (
                        ve[0, i] * rg[e, 0, j]
                        + ve[1, i] * rg[e, 1, j]
                        + ve[2, i] * rg[e, 2, j]
                        + ve[3, i] * rg[e, 3, j]
                    )
            vol = volumes[e]
            tr = vol * lam * (g[0, 0] + g[1, 1] + g[2, 2])
            vm = vol * mu
            for i in range(3):
                for k in range(3):
                    mm[i, k] = vm * (g[i, k] + g[k, i])
                mm[i, i] += tr
            if with_t:
                t = t_world[e]
                w0, w1, w2 = g[2, 1] - g[1, 2], g[0, 2] - g[2, 0], g[1, 0] - g[0, 1]
                h = 0.5 * vol
                t0 = h * (t[0, 0] * w0 + t[0, 1] * w1 + t[0, 2] * w2)
                t1 = h * (t[1, 0] * w0 + t[1, 1] * w1 + t[1, 2] * w2)
                t2 = h * (t[2, 0] * w0 + t[2, 1] * w1 + t[2, 2] * w2)
                mm[0, 1] -= t2
                mm[0, 2] += t1
                mm[1, 0] += t2
                mm[1, 2] -= t0
                mm[2, 0] -= t1
                mm[2, 1] += t0
            for a in range(4):
                for i in range(3):
                    e_rows[4 * e + a, i] = (
                        mm[i, 0] * rg[e, a, 0] + mm[i, 1] * rg[e, a, 1] + mm[i, 2] * rg[e, a, 2]
                    )
    sums = np.empty((ptr.shape[0] - 1, 3))
    gather_rows(e_rows, ptr, rows, sums)
    out = np.zeros(n_out)
    for a in range(sums.shape[0]):
        for i in range(3):
            k = dof[a, i]
            if k >= 0:
                out[k] = sums[a, i]
    return out


@njit(cache=True, nogil=True, parallel=True)
def skew_stiffness_closed_form(f, rot, lam, mu, project) -> tuple[np.ndarray, np.ndarray]:
    """(t, easy): the rotation-derivative term T' = R (2 mu I + 2 c Q^-1) R^T (m, 3, 3)
    of `corotation.skew_stiffness` (Q = tr S I - S, S = sym(R^T F), c = lam tr(S - I) -
    2 mu) with Q^-1 from its adjugate, for the elements where that is safe (`easy`):
    Q well conditioned and, with `project`, Gershgorin's bound showing that clamping
    T's eigenvalues at zero would change nothing. The caller does the rest by eigh."""
    m = f.shape[0]
    t = np.zeros((m, 3, 3))
    easy = np.zeros(m, dtype=np.bool_)
    nblocks = n_blocks(m)
    for blk in prange(nblocks):
        s = np.empty((3, 3))
        q = np.empty((3, 3))
        adj = np.empty((3, 3))
        te = np.empty((3, 3))
        lo, hi = block_range(blk, nblocks, m)
        for e in range(lo, hi):
            r = rot[e]
            _rt_f(r, f[e], s)
            for i in range(3):
                for j in range(i + 1, 3):
                    v = 0.5 * (s[i, j] + s[j, i])
                    s[i, j] = v
                    s[j, i] = v
            tr = s[0, 0] + s[1, 1] + s[2, 2]
            c = lam * (tr - 3.0) - 2.0 * mu
            for i in range(3):
                for j in range(3):
                    q[i, j] = -s[i, j]
                q[i, i] += tr
            for i in range(3):
                i1, i2 = (i + 1) % 3, (i + 2) % 3
                for j in range(3):
                    j1, j2 = (j + 1) % 3, (j + 2) % 3
                    adj[j, i] = q[i1, j1] * q[i2, j2] - q[i1, j2] * q[i2, j1]
            det_q = q[0, 0] * adj[0, 0] + q[0, 1] * adj[1, 0] + q[0, 2] * adj[2, 0]
            ok = det_q > 1e-6 * abs(tr) ** 3
            if ok and project:
                q_low = min(
                    q[0, 0] - abs(q[0, 1]) - abs(q[0, 2]),
                    q[1, 1] - abs(q[1, 2]) - abs(q[1, 0]),
                    q[2, 2] - abs(q[2, 0]) - abs(q[2, 1]),
                )
                ok = q_low > 0.0 and (c >= 0.0 or mu * q_low + c >= 0.0)
            if not ok:
                continue
            easy[e] = True
            k = 2.0 * c / det_q
            for i in range(3):
                for j in range(3):
                    te[i, j] = k * adj[i, j]
                te[i, i] += 2.0 * mu
            for i in range(3):  # R te R^T
                for j in range(3):
                    acc = 0.0
                    for a in range(3):
                        ra = r[i, a]
                        for b in range(3):
                            acc += ra * te[a, b] * r[j, b]
                    t[e, i, j] = acc
    return t, easy


def warm_up() -> None:
    """Compile (or load from the disk cache) every kernel on one tet, so that the first
    state's timing does not include it (about 0.5 s from the cache, 5 s compiling)."""
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    tets = np.array([[0, 1, 2, 3]], dtype=np.int64)
    grads = np.array([[[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]])
    eye = np.eye(3).reshape(1, 3, 3)
    f, rot, _, _ = kinematics(x, tets, grads, eye, True, 4, 1e-7)
    kinematics(x, tets, grads, np.empty((0, 3, 3)), False, 4, 1e-7)
    forces_and_energy(tets, grads, np.ones(1), 1.0, 1.0, f, rot, *node_incidence(tets, 4))
    tangent_product(tets, grads, np.ones(1), 1.0, 1.0, rot, eye.copy(), True, x)
    tangent_product(tets, grads, np.ones(1), 1.0, 1.0, rot, np.empty((0, 3, 3)), False, x)
    for project in (True, False):
        skew_stiffness_closed_form(f, rot, 1.0, 1.0, project)
