"""Hyperelastic materials split into an isochoric and a volumetric part,
psi(F) = W(I1bar) + U(J), I1bar = J^(-2/3) tr(F^T F), with

- W(I1bar) = C10 (I1bar - 3) + C20 (I1bar - 3)^2 + C30 (I1bar - 3)^3 (Yeoh; the
  neo-Hookean solid is C10 = mu / 2, C20 = C30 = 0), constants in kPa;
- U(J) = kappa / 4 (J^2 - 1 - 2 ln J) (Simo and Taylor's; convex, infinite as J -> 0),
  kappa the bulk modulus (kPa).

Each function works on one quadrature point and is compiled with numba; stresses are
first Piola-Kirchhoff P (kPa) and tangents A = dP/dF (kPa) as 9 x 9 matrices indexed
[3 i + J, 3 k + L] for P_iJ and F_kL. kPa * mm^3 = mN mm (the FEM's energy unit).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def isochoric(f, finv, det, c10, c20, c30, want_tangent, p_out, a_out, d) -> float:
    """W(I1bar) (kPa) at F (3, 3) with F^-1 `finv` and det F `det`; writes P (3, 3) into
    p_out and, when want_tangent, dP/dF (9, 9) into a_out, its blocks [3 i + J, 3 k + L]
    with k >= i only (the others are their transposes, A_iJkL = A_kLiJ, and are left as
    they were: the element loop reads only these); d (3, 3): scratch (the element loop
    runs on several threads, where an allocation per call is slow)."""
    i1 = 0.0
    for i in range(3):
        for j in range(3):
            i1 += f[i, j] * f[i, j]
    c = det ** (-2.0 / 3.0)
    t = c * i1 - 3.0
    w = c10 * t + c20 * t * t + c30 * t * t * t
    w1 = c10 + 2.0 * c20 * t + 3.0 * c30 * t * t
    w2 = 2.0 * c20 + 6.0 * c30 * t
    # d: dI1bar/dF
    for i in range(3):
        for jj in range(3):
            d[i, jj] = 2.0 * c * (f[i, jj] - i1 / 3.0 * finv[jj, i])
            p_out[i, jj] = w1 * d[i, jj]
    if want_tangent:
        for i in range(3):
            for jj in range(3):
                r = 3 * i + jj
                for k in range(i, 3):
                    for ll in range(3):
                        d2 = (
                            -(2.0 / 3.0) * finv[ll, k] * (f[i, jj] - i1 / 3.0 * finv[jj, i])
                            - (2.0 / 3.0) * f[k, ll] * finv[jj, i]
                            + i1 / 3.0 * finv[jj, k] * finv[ll, i]
                        )
                        if i == k and jj == ll:
                            d2 += 1.0
                        a_out[r, 3 * k + ll] = w2 * d[i, jj] * d[k, ll] + w1 * 2.0 * c * d2
    return w


@njit(cache=True, nogil=True)
def volumetric(det: float, kappa: float) -> tuple[float, float, float]:
    """(U, dU/dJ, d2U/dJ2) in kPa at J = det."""
    return (
        0.25 * kappa * (det * det - 1.0 - 2.0 * np.log(det)),
        0.5 * kappa * (det - 1.0 / det),
        0.5 * kappa * (1.0 + 1.0 / (det * det)),
    )
