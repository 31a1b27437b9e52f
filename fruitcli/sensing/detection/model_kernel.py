"""Compiled least-squares fit of one touch's footprint (numba), for `model_fit`.

Units: grid units (taxel pitches), mm, counts. One touch at a time: the contact point
c(a, b) = sum_m coef[m] phi_m(a, b), phi = (1, a, b, a^2, a b, b^2), on the surface the
window's taxels span (a, b in grid units from the window's centre taxel); taxel k of
the window reads

    m_k = A g_k f(|c(a, b) - P_k| / s)

with f the skin's radial footprint at its calibrated width (tabulated, f(0) = 1), A the
amplitude (counts), s the width's scale and g_k the taxel's gain. The residuals
(m_k - v_k) / e_k, e_k the noise of taxel k, and a prior (s - 1) / width_prior on the
width are minimised by Levenberg-Marquardt steps from the N9 start within bounds on
(a, b, A, s). Releases the GIL.
"""

from __future__ import annotations

import numpy as np
from numba import njit

N_PARAMS = 4  # a, b, A, s


@njit(cache=True, nogil=True)
def _profile(x, profile, step):
    """f(x) and f'(x) of the tabulated profile (linear between samples, 0 beyond)."""
    u = x / step
    k = int(u)
    if k >= profile.shape[0] - 1:
        return 0.0, 0.0
    t = u - k
    slope = (profile[k + 1] - profile[k]) / step
    return profile[k] + t * (profile[k + 1] - profile[k]), slope


@njit(cache=True, nogil=True)
def _point(coef, a, b):
    """c(a, b) (3,) and its derivatives dc/da, dc/db."""
    c = np.empty(3)
    ca = np.empty(3)
    cb = np.empty(3)
    for d in range(3):
        c[d] = (
            coef[0, d]
            + coef[1, d] * a
            + coef[2, d] * b
            + coef[3, d] * a * a
            + coef[4, d] * a * b
            + coef[5, d] * b * b
        )
        ca[d] = coef[1, d] + 2.0 * coef[3, d] * a + coef[4, d] * b
        cb[d] = coef[2, d] + coef[4, d] * a + 2.0 * coef[5, d] * b
    return c, ca, cb


@njit(cache=True, nogil=True)
def _residuals(x, v, inv_e, gain, pos, coef, profile, step, width_prior, jac, res):
    """Weighted residuals res (K + 1,) at x, the last the width prior (s - 1) /
    width_prior, and their Jacobian jac (K + 1, 4); returns chi^2."""
    a, b, amp, s = x[0], x[1], x[2], x[3]
    c, ca, cb = _point(coef, a, b)
    kp = v.shape[0]
    res[kp] = (s - 1.0) / width_prior
    jac[kp, 0] = 0.0
    jac[kp, 1] = 0.0
    jac[kp, 2] = 0.0
    jac[kp, 3] = 1.0 / width_prior
    chi2 = res[kp] * res[kp]
    for k in range(v.shape[0]):
        dx = c[0] - pos[k, 0]
        dy = c[1] - pos[k, 1]
        dz = c[2] - pos[k, 2]
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        f, fp = _profile(d / s, profile, step)
        m = amp * gain[k] * f
        res[k] = (m - v[k]) * inv_e[k]
        chi2 += res[k] * res[k]
        dd_da = 0.0
        dd_db = 0.0
        if d > 1e-9:
            dd_da = (dx * ca[0] + dy * ca[1] + dz * ca[2]) / d
            dd_db = (dx * cb[0] + dy * cb[1] + dz * cb[2]) / d
        g = amp * gain[k] * fp / s * inv_e[k]
        jac[k, 0] = g * dd_da
        jac[k, 1] = g * dd_db
        jac[k, 2] = gain[k] * f * inv_e[k]
        jac[k, 3] = -g * d / s
    return chi2


@njit(cache=True, nogil=True)
def fit_one(
    x0, lo, hi, v, inv_e, gain, pos, coef, profile, step, width_prior, iterations, out, cov
) -> None:
    """Fit x = (a, b, A, s) from x0 within [lo, hi]; out = (a, b, A, s, chi^2 of the
    taxels, steps taken), cov (4, 4) = (J^T J)^-1 at the solution (zeros when
    singular)."""
    k = v.shape[0] + 1
    x = x0.copy()
    jac = np.empty((k, N_PARAMS))
    res = np.empty(k)
    jac_t = np.empty((k, N_PARAMS))
    res_t = np.empty(k)
    chi2 = _residuals(x, v, inv_e, gain, pos, coef, profile, step, width_prior, jac, res)
    lam = 1e-3
    taken = 0
    for _ in range(iterations):
        jtj = jac.T @ jac
        jtr = jac.T @ res
        improved = False
        for _try in range(8):
            m = jtj.copy()
            for p in range(N_PARAMS):
                m[p, p] += lam * (jtj[p, p] + 1e-12)
            try:
                dx = np.linalg.solve(m, -jtr)
            except Exception:  # a singular system: damp more
                lam *= 10.0
                continue
            xt = np.minimum(np.maximum(x + dx, lo), hi)
            chi2_t = _residuals(
                xt, v, inv_e, gain, pos, coef, profile, step, width_prior, jac_t, res_t
            )
            if chi2_t < chi2:
                x, chi2 = xt, chi2_t
                jac[:, :] = jac_t
                res[:] = res_t
                lam = max(lam * 0.3, 1e-7)
                improved = True
                taken += 1
                break
            lam *= 10.0
        if not improved:
            break
        if np.abs(dx).max() < 1e-5:
            break
    for p in range(N_PARAMS):
        out[p] = x[p]
    out[4] = chi2 - res[k - 1] * res[k - 1]
    out[5] = taken
    jtj = jac.T @ jac
    cov[:, :] = 0.0
    if abs(np.linalg.det(jtj)) > 1e-300:
        cov[:, :] = np.linalg.inv(jtj)


@njit(cache=True, nogil=True)
def fit_all(
    x0, lo, hi, v, inv_e, gain, pos, coef, profile, step, width_prior, iterations, out, cov
) -> None:
    """`fit_one` for every touch: x0, lo, hi (n, 4), v, inv_e, gain (n, K), pos (n, K, 3),
    coef (n, 6, 3); writes out (n, 6) and cov (n, 4, 4)."""
    for t in range(x0.shape[0]):
        fit_one(
            x0[t],
            lo[t],
            hi[t],
            v[t],
            inv_e[t],
            gain[t],
            pos[t],
            coef[t],
            profile,
            step,
            width_prior,
            iterations,
            out[t],
            cov[t],
        )


@njit(cache=True, nogil=True)
def surface_point(coef, a, b) -> tuple:
    """c(a, b) (3,) mm and the tangents dc/da, dc/db, for the results."""
    return _point(coef, a, b)
