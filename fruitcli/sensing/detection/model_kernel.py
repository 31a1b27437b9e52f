"""Compiled least-squares fit of one touch's footprint (numba), for `model_fit`.

Units: grid units (taxel pitches), mm, counts. One touch at a time: the contact point
c(a, b) = sum_m coef[m] phi_m(a, b) + r(a, b), phi = (1, a, b, a^2, a b, b^2), on the
surface the window's taxels span (a, b in grid units from the window's centre taxel;
r the bilinear interpolation of the quadratic's misfit at the taxels, so c passes
through each of them, or, where the body's surface is known, of the way from the
quadratic to the surface on a finer lattice, so c runs over the body itself); taxel k
of the window reads

    m_k = A g_k f(sqrt(r_k^2 + alpha h_k^2) / (s + omega |h_k|)) exp(-kappa |h_k|)

with f the skin's radial footprint at its calibrated width (tabulated, f(0) = 1), A the
amplitude (counts), s the width's scale, g_k the taxel's gain, h_k the z component of
c - P_k (the contact point's height over the taxel: z is the bench's approach), r_k the
rest of |c - P_k|, alpha the weight of h in the distance, kappa (per mm) the share
of it taken as gap over the gap decay and omega (per mm) the footprint's widening with
that gap (``height``; 1, 0 and 0: f of the 3D distance). The residuals
(m_k - v_k) / e_k, e_k the noise of taxel k, and a prior (s - 1) / width_prior on the
width are minimised by Levenberg-Marquardt steps from the N9 start within bounds on
(a, b, A, s). Releases the GIL.
"""

from __future__ import annotations

import numpy as np
from numba import njit

N_PARAMS = 4  # a, b, A, s
STEP_TOLERANCE = 1e-3  # a step smaller than this (grid units, width scale, A relative) ends


@njit(cache=True, nogil=True)
def _profile(x, profile, inv_step):
    """f(x) and f'(x) of the tabulated profile, samples 1 / inv_step apart (linear between
    samples, 0 beyond)."""
    u = x * inv_step
    k = int(u)
    if k >= profile.shape[0] - 1:
        return 0.0, 0.0
    t = u - k
    rise = profile[k + 1] - profile[k]
    return profile[k] + t * rise, rise * inv_step


@njit(cache=True, nogil=True)
def _point(coef, corr, sub, a, b, pt):
    """pt (3, 3) = c(a, b) and its derivatives dc/da, dc/db: the quadratic map plus the bilinear
    interpolation of the corrections `corr` (L, L, 3), a lattice of `sub` nodes per
    grid cell over the window (L = 2 half sub + 1): the map's misfit at the taxels
    (sub = 1; a cell without a taxel has misfit 0), so c passes through every taxel, or
    the way from the map to the body's surface (`surface_chart`)."""
    last = corr.shape[0] - 1
    half = last / (2.0 * sub)
    c, ca, cb = pt[0], pt[1], pt[2]
    u = min(max((a + half) * sub, 0.0), float(last))
    w = min(max((b + half) * sub, 0.0), float(last))
    i0 = min(int(u), last - 1)
    j0 = min(int(w), last - 1)
    tu = u - i0
    tw = w - j0
    inside_a = float(sub) if 0.0 < (a + half) * sub < last else 0.0
    inside_b = float(sub) if 0.0 < (b + half) * sub < last else 0.0
    for d in range(3):
        c00 = corr[i0, j0, d]
        c10 = corr[i0 + 1, j0, d]
        c01 = corr[i0, j0 + 1, d]
        c11 = corr[i0 + 1, j0 + 1, d]
        r = (1 - tu) * (1 - tw) * c00 + tu * (1 - tw) * c10 + (1 - tu) * tw * c01 + tu * tw * c11
        ra = ((1 - tw) * (c10 - c00) + tw * (c11 - c01)) * inside_a
        rb = ((1 - tu) * (c01 - c00) + tu * (c11 - c10)) * inside_b
        c[d] = (
            coef[0, d]
            + coef[1, d] * a
            + coef[2, d] * b
            + coef[3, d] * a * a
            + coef[4, d] * a * b
            + coef[5, d] * b * b
            + r
        )
        ca[d] = coef[1, d] + 2.0 * coef[3, d] * a + coef[4, d] * b + ra
        cb[d] = coef[2, d] + coef[4, d] * a + 2.0 * coef[5, d] * b + rb


@njit(cache=True, nogil=True)
def _residuals(
    x, v, inv_e, gain, pos, coef, corr, sub, profile, step, height, width_prior, jac, res, pt
):
    """Weighted residuals res (K + 1,) at x, the last the width prior (s - 1) /
    width_prior, and their Jacobian jac (K + 1, 4); returns chi^2. height (3,): alpha,
    kappa and omega (per mm). pt (3, 3): scratch."""
    a, b, amp, s = x[0], x[1], x[2], x[3]
    _point(coef, corr, sub, a, b, pt)
    c, ca, cb = pt[0], pt[1], pt[2]
    kp = v.shape[0]
    res[kp] = (s - 1.0) / width_prior
    jac[kp, 0] = 0.0
    jac[kp, 1] = 0.0
    jac[kp, 2] = 0.0
    jac[kp, 3] = 1.0 / width_prior
    chi2 = res[kp] * res[kp]
    inv_s, inv_step = 1.0 / s, 1.0 / step  # multiplications in the loop, not divisions
    alpha, kappa, omega = height[0], height[1], height[2]
    for k in range(v.shape[0]):
        dx = c[0] - pos[k, 0]
        dy = c[1] - pos[k, 1]
        dz = c[2] - pos[k, 2]
        az = alpha * dz
        d = np.sqrt(dx * dx + dy * dy + az * dz)
        inv_w = inv_s  # 1 / (s + omega |h|): the width's scale at this taxel
        if omega != 0.0:
            inv_w = 1.0 / (s + omega * abs(dz))
        f, fp = _profile(d * inv_w, profile, inv_step)
        dgap = 0.0  # d(kappa |h|) / dh
        if kappa != 0.0:
            fall = np.exp(-kappa * abs(dz))
            f *= fall
            fp *= fall
            dgap = kappa if dz > 0.0 else (-kappa if dz < 0.0 else 0.0)
        m = amp * gain[k] * f
        res[k] = (m - v[k]) * inv_e[k]
        chi2 += res[k] * res[k]
        dd_da = 0.0
        dd_db = 0.0
        if d > 1e-9:
            inv_d = 1.0 / d
            dd_da = (dx * ca[0] + dy * ca[1] + az * ca[2]) * inv_d
            dd_db = (dx * cb[0] + dy * cb[1] + az * cb[2]) * inv_d
        g = amp * gain[k] * fp * inv_w * inv_e[k]
        jac[k, 0] = g * dd_da
        jac[k, 1] = g * dd_db
        jac[k, 2] = gain[k] * f * inv_e[k]
        jac[k, 3] = -g * d * inv_w
        if omega != 0.0 and dz != 0.0:  # the width grows with |h| too
            wide = g * d * inv_w * omega * (1.0 if dz > 0.0 else -1.0)
            jac[k, 0] -= wide * ca[2]
            jac[k, 1] -= wide * cb[2]
        if dgap != 0.0:
            slope = amp * gain[k] * f * inv_e[k] * dgap
            jac[k, 0] -= slope * ca[2]
            jac[k, 1] -= slope * cb[2]
    return chi2


@njit(cache=True, nogil=True)
def _normal(jac, res, m, jtj, jtr):
    """J^T J (4, 4) and J^T r (4,) over the first m rows, by loops (no allocation)."""
    for p in range(N_PARAMS):
        jtr[p] = 0.0
        for q in range(N_PARAMS):
            jtj[p, q] = 0.0
    for k in range(m):
        for p in range(N_PARAMS):
            jp = jac[k, p]
            jtr[p] += jp * res[k]
            for q in range(p, N_PARAMS):
                jtj[p, q] += jp * jac[k, q]
    for p in range(N_PARAMS):
        for q in range(p):
            jtj[p, q] = jtj[q, p]


@njit(cache=True, nogil=True)
def _cholesky(a, low) -> bool:
    """Lower Cholesky factor of the small symmetric matrix a (p, p) into low; False when
    a is not positive definite."""
    p = a.shape[0]
    for i in range(p):
        for j in range(i + 1):
            t = a[i, j]
            for k in range(j):
                t -= low[i, k] * low[j, k]
            if i == j:
                if t <= 0.0:
                    return False
                low[i, i] = np.sqrt(t)
            else:
                low[i, j] = t / low[j, j]
        for j in range(i + 1, p):
            low[i, j] = 0.0
    return True


@njit(cache=True, nogil=True)
def _solve(low, b, x, y):
    """x = (L L^T)^-1 b for b, x (p,); y (p,): scratch."""
    p = low.shape[0]
    for i in range(p):
        t = b[i]
        for k in range(i):
            t -= low[i, k] * y[k]
        y[i] = t / low[i, i]
    for i in range(p - 1, -1, -1):
        t = y[i]
        for k in range(i + 1, p):
            t -= low[k, i] * x[k]
        x[i] = t / low[i, i]


@njit(cache=True, nogil=True)
def fit_one(
    x0,
    lo,
    hi,
    v,
    inv_e,
    gain,
    pos,
    coef,
    corr,
    sub,
    profile,
    step,
    height,
    width_prior,
    iterations,
    out,
    cov,
    work_jac,
    work_res,
    work_vec,
    work_mat,
) -> None:
    """Fit x = (a, b, A, s) from x0 within [lo, hi] (`height`: alpha, kappa, omega of the
    footprint); out = (a, b, A, s, chi^2 of the
    taxels, steps taken), cov (4, 4) = (J^T J)^-1 at the solution (zeros when
    singular). Scratch: `work_jac` (2, K + 1, 4), `work_res` (2, K + 1), `work_vec`
    (8, 4), `work_mat` (4, 4, 4) (no allocation per fit)."""
    m = v.shape[0] + 1
    jac, jac_t = work_jac[0], work_jac[1]
    res, res_t = work_res[0], work_res[1]
    x, xt, dx, rhs = work_vec[0], work_vec[1], work_vec[2], work_vec[3]
    jtr, e, col, y = work_vec[4], work_vec[5], work_vec[6], work_vec[7]
    jtj, damped, low, pt = work_mat[0], work_mat[1], work_mat[2], work_mat[3, :3, :3]
    x[:] = x0
    chi2 = _residuals(
        x, v, inv_e, gain, pos, coef, corr, sub, profile, step, height, width_prior, jac, res, pt
    )
    lam = 1e-3
    taken = 0
    for _ in range(iterations):
        _normal(jac, res, m, jtj, jtr)
        improved = False
        biggest = 0.0
        for _try in range(8):
            for p in range(N_PARAMS):
                for q in range(N_PARAMS):
                    damped[p, q] = jtj[p, q]
                damped[p, p] += lam * (jtj[p, p] + 1e-12)
                rhs[p] = -jtr[p]
            if not _cholesky(damped, low):
                lam *= 10.0
                continue
            _solve(low, rhs, dx, y)
            biggest = 0.0
            for p in range(N_PARAMS):
                xt[p] = min(max(x[p] + dx[p], lo[p]), hi[p])
                scale = max(abs(x[p]), 1.0) if p == 2 else 1.0  # the amplitude: relative
                biggest = max(biggest, abs(xt[p] - x[p]) / scale)
            chi2_t = _residuals(
                xt, v, inv_e, gain, pos, coef, corr, sub, profile, step, height, width_prior,
                jac_t, res_t, pt,
            )  # fmt: skip
            if chi2_t < chi2:
                x[:] = xt
                chi2 = chi2_t
                jac[:m, :] = jac_t[:m, :]
                res[:m] = res_t[:m]
                lam = max(lam * 0.3, 1e-7)
                improved = True
                taken += 1
                break
            lam *= 10.0
        if not improved or biggest < STEP_TOLERANCE:
            break
    for p in range(N_PARAMS):
        out[p] = x[p]
    out[4] = chi2 - res[m - 1] * res[m - 1]
    out[5] = taken
    _normal(jac, res, m, jtj, jtr)
    cov[:, :] = 0.0
    if _cholesky(jtj, low):
        for p in range(N_PARAMS):
            e[:] = 0.0
            e[p] = 1.0
            _solve(low, e, col, y)
            for q in range(N_PARAMS):
                cov[q, p] = col[q]


@njit(cache=True, nogil=True)
def fit_all(
    x0,
    lo,
    hi,
    v,
    inv_e,
    gain,
    pos,
    coef,
    corr,
    sub,
    profile,
    step,
    height,
    width_prior,
    iterations,
    out,
    cov,
    xyz,
    var_mm2,
) -> None:
    """`fit_one` for every touch: x0, lo, hi (n, 4), v, inv_e, gain (n, K), pos (n, K, 3),
    coef (n, 6, 3), corr (n, L, L, 3) with `sub` lattice nodes per cell, the footprint's
    `height` (3,) (alpha, kappa and omega per mm); writes out
    (n, 6), cov (n, 4, 4), the point xyz (n, 3) mm and var_mm2 (n,), the trace of the
    point's covariance in mm^2."""
    kk = v.shape[1]
    work_jac = np.empty((2, kk + 1, N_PARAMS))
    work_res = np.empty((2, kk + 1))
    work_vec = np.empty((8, N_PARAMS))
    work_mat = np.empty((4, N_PARAMS, N_PARAMS))
    vt, et, gt, pt = np.empty(kk), np.empty(kk), np.empty(kk), np.empty((kk, 3))
    here = np.empty((3, 3))
    for t in range(x0.shape[0]):
        u = 0  # the window's taxels with weight, in order (the others add exact zeros)
        for k in range(kk):
            if inv_e[t, k] != 0.0:
                vt[u], et[u], gt[u] = v[t, k], inv_e[t, k], gain[t, k]
                pt[u, :] = pos[t, k, :]
                u += 1
        fit_one(
            x0[t],
            lo[t],
            hi[t],
            vt[:u],
            et[:u],
            gt[:u],
            pt[:u],
            coef[t],
            corr[t],
            sub,
            profile,
            step,
            height,
            width_prior,
            iterations,
            out[t],
            cov[t],
            work_jac,
            work_res,
            work_vec,
            work_mat,
        )
        _point(coef[t], corr[t], sub, out[t, 0], out[t, 1], here)
        c, ca, cb = here[0], here[1], here[2]
        xyz[t, :] = c
        var = 0.0
        for d in range(3):
            var += (
                ca[d] * ca[d] * cov[t, 0, 0]
                + 2.0 * ca[d] * cb[d] * cov[t, 0, 1]
                + cb[d] * cb[d] * cov[t, 1, 1]
            )
        var_mm2[t] = var


@njit(cache=True, nogil=True)
def map_factors(win, basis, map_weight, low, ok) -> None:
    """The Cholesky factors low (T, 6, 6) of each window's surface-map normal matrix,
    sum over its taxels of map_weight basis basis^T plus a light ridge on the
    non-constant terms; win (T, K) each taxel's window (-1: no taxel), basis (K, 6);
    ok (T,) False where the matrix is not positive definite. The matrix depends on the
    window's cells only, so `prepare` reuses it for every touch centred there."""
    nb = basis.shape[1]
    lhs = np.empty((nb, nb))
    for t in range(win.shape[0]):
        lhs[:, :] = 0.0
        for k in range(win.shape[1]):
            if win[t, k] < 0:
                continue
            for p in range(nb):
                for q in range(nb):
                    lhs[p, q] += basis[k, p] * map_weight[k] * basis[k, q]
        trace = 0.0
        for p in range(nb):
            trace += lhs[p, p]
        for p in range(1, nb):
            lhs[p, p] += 1e-9 * max(trace, 1e-12)
        ok[t] = _cholesky(lhs, low[t])


@njit(cache=True, nogil=True)
def prepare(
    frame,
    row,
    centre,
    win,
    n9_taxels,
    v,
    taxel_gain,
    noise,
    model_error,
    pos,
    basis,
    map_weight,
    map_low,
    map_ok,
    vw,
    inv_e,
    gain,
    coef,
    corr,
    used,
) -> None:
    """Each touch's window (n rows, touches of one frame next to each other, `frame` (n,)
    their frames, `row` (n,) their rows of `v`, `centre` (n,) their peak taxels): its
    activations vw, inverse errors inv_e and gains (n, K) (0 weight where no taxel, or
    where a taxel lies in another touch's N9 of the frame), the surface map coef (n, 6, 3)
    fitted to its taxels' positions pos (n, K, 3) (N9 weight 1, ring `map_weight`, the
    factors `map_low`, `map_ok` of `map_factors`) and its misfit corr (n, W, W, 3) at
    the taxels; `used` (n,) the taxels fitted. v (F, T) activations, taxel_gain (T,),
    noise (n, T) (counts std of each taxel in each touch's activations)."""
    n, kk = win.shape
    side = corr.shape[1]
    nb = basis.shape[1]
    rhs = np.empty((3, nb))  # a row per coordinate: each a contiguous right-hand side
    col = np.empty(nb)
    y = np.empty(nb)
    for t in range(n):
        lo = t
        while lo > 0 and frame[lo - 1] == frame[t]:
            lo -= 1
        hi = t
        while hi < n - 1 and frame[hi + 1] == frame[t]:
            hi += 1
        count = 0
        rhs[:, :] = 0.0
        for k in range(kk):
            w = win[t, k]
            vw[t, k] = 0.0
            inv_e[t, k] = 0.0
            gain[t, k] = 1.0
            if w < 0:
                continue
            for p in range(nb):
                for d in range(3):
                    rhs[d, p] += basis[k, p] * map_weight[k] * pos[t, k, d]
            other = False
            for u in range(lo, hi + 1):
                if u == t:
                    continue
                for m in range(n9_taxels.shape[1]):
                    if n9_taxels[u, m] == w:
                        other = True
            if other:
                continue
            x = v[row[t], w]
            vw[t, k] = x
            gain[t, k] = taxel_gain[w]
            e = noise[t, w]
            inv_e[t, k] = 1.0 / max(np.sqrt(e * e + (model_error * x) ** 2), 1e-9)
            count += 1
        used[t] = count
        c = centre[t]
        if map_ok[c]:
            for d in range(3):
                _solve(map_low[c], rhs[d], col, y)
                coef[t, :, d] = col
        else:
            coef[t, :, :] = 0.0
        for k in range(kk):
            i = k // side
            j = k % side
            for d in range(3):
                if win[t, k] < 0:
                    corr[t, i, j, d] = 0.0
                    continue
                fitted = 0.0
                for p in range(nb):
                    fitted += basis[k, p] * coef[t, p, d]
                corr[t, i, j, d] = pos[t, k, d] - fitted
