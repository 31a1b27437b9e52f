"""Element loops of the hyperelastic FEM (compiled with numba, GIL released): strain
energy, internal forces and element tangents of any Lagrange tet family with any
material of `fruitcli.fem.materials.hyperelastic`.

Per element e and quadrature point q: F = sum_a x_a (x) dN[e, q, a] (reference
gradients, 1/mm), weight wq[e, q] (mm^3). The volumetric energy is taken either per
point, sum_q wq U(J_q), or, with `mean_dilatation`, on the element's mean volume ratio
theta = sum_q wq J_q / V_e as V_e U(theta) (a constant pressure per element: the P2/P0
mixed element with the pressure condensed, free of volumetric locking).
Units: mm, kPa, mN.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from fruitcli.fem.element_sums import block_range, gather_rows, n_blocks
from fruitcli.fem.materials.hyperelastic import isochoric, volumetric


@njit(cache=True, nogil=True)
def _inverse(f, out):
    """F^-1 into out; returns det F."""
    c00 = f[1, 1] * f[2, 2] - f[1, 2] * f[2, 1]
    c01 = f[1, 2] * f[2, 0] - f[1, 0] * f[2, 2]
    c02 = f[1, 0] * f[2, 1] - f[1, 1] * f[2, 0]
    det = f[0, 0] * c00 + f[0, 1] * c01 + f[0, 2] * c02
    if det == 0.0:
        return 0.0
    inv = 1.0 / det
    out[0, 0] = c00 * inv
    out[1, 0] = c01 * inv
    out[2, 0] = c02 * inv
    out[0, 1] = (f[0, 2] * f[2, 1] - f[0, 1] * f[2, 2]) * inv
    out[1, 1] = (f[0, 0] * f[2, 2] - f[0, 2] * f[2, 0]) * inv
    out[2, 1] = (f[0, 1] * f[2, 0] - f[0, 0] * f[2, 1]) * inv
    out[0, 2] = (f[0, 1] * f[1, 2] - f[0, 2] * f[1, 1]) * inv
    out[1, 2] = (f[0, 2] * f[1, 0] - f[0, 0] * f[1, 2]) * inv
    out[2, 2] = (f[0, 0] * f[1, 1] - f[0, 1] * f[1, 0]) * inv
    return det


@njit(cache=True, nogil=True, parallel=True)
def evaluate(
    x, conn, dn, wq, consts, mean_dilatation, want_tangent, forces, blocks, jmin, ptr, rows
) -> float:
    """Strain energy (mN mm) at node positions x (n, 3); writes the internal forces
    dPsi/dx (n, 3, mN) into `forces`, element tangents (m, 3 nen, 3 nen, mN/mm) into
    `blocks` when want_tangent (zero for an inverted element), and each element's
    smallest det F into jmin (m,). Returns -1.0 when some det F <= 0 (energy
    undefined). The elements run over every core in blocks; each node sums its
    elements' force rows in element order (ptr, rows: `element_sums.node_incidence`)
    and the energy sums the elements' in element order, so the result does not depend
    on the number of threads.

    Per element: F (`_deformation`), then point by point the energy, the forces
    (`_add_point_forces`) and the moduli (`isochoric`, `_add_volumetric_moduli`: the
    blocks k >= i of A_iJkL only) contracted with the shape gradients
    (`_add_point_tangent`) into the element's own tangent, written out once with its
    other half by symmetry and the mean dilatation's rank-one term: on the default
    Fruit's 8,865 quadratic tets (one thread) 40 ms instead of 51 ms for the forces
    and tangents together (9 ms for the forces alone)."""
    m, nq, nen = dn.shape[0], dn.shape[1], dn.shape[2]
    c10, c20, c30, kappa = consts[0], consts[1], consts[2], consts[3]
    e_rows = np.zeros((m * nen, 3))
    e_energy = np.zeros(m)
    nblocks = n_blocks(m)
    for blk in prange(nblocks):
        fq = np.empty((nq, 3, 3))
        finv = np.empty((nq, 3, 3))
        det = np.empty(nq)
        p_iso = np.empty((3, 3))
        d_iso = np.empty((3, 3))
        a = np.empty((9, 9))
        fe = np.empty((nen, 3))
        b = np.empty((nen, 3))
        gt = np.empty((3, nen))  # the point's shape gradients, transposed
        ga = np.empty((nen, 3))  # dN_aJ A_iJkL summed over J: [a, L] for one (i, k)
        kb = np.empty((3, 3, nen, nen))  # the element tangent as [i, k, a, b]
        lo_e, hi_e = block_range(blk, nblocks, m)
        for e in range(lo_e, hi_e):
            jmin[e] = _deformation(x, conn[e], dn[e], fq, finv, det)
            if jmin[e] <= 0.0:  # inverted: no energy, and a zero tangent, not stale memory
                if want_tangent:
                    blocks[e, :, :] = 0.0
                continue
            ve = 0.0
            theta = 0.0
            for q in range(nq):
                ve += wq[e, q]
                theta += wq[e, q] * det[q]
            theta /= ve
            energy = 0.0
            u_e, u1_e, u2_e = volumetric(theta, kappa)
            if mean_dilatation:
                energy = ve * u_e
            fe[:, :] = 0.0
            b[:, :] = 0.0
            if want_tangent:
                kb[:, :, :, :] = 0.0
            for q in range(nq):
                w = wq[e, q]
                jq = det[q]
                energy += w * isochoric(
                    fq[q], finv[q], jq, c10, c20, c30, want_tangent, p_iso, a, d_iso
                )
                if mean_dilatation:
                    u1, u2 = u1_e, 0.0
                else:
                    u_q, u1, u2 = volumetric(jq, kappa)
                    energy += w * u_q
                _add_point_forces(dn[e, q], finv[q], jq, w, u1, p_iso, fe, b)
                if not want_tangent:
                    continue
                _add_volumetric_moduli(finv[q], jq, u1, u2, mean_dilatation, a)
                _add_point_tangent(dn[e, q], w, a, gt, ga, kb)
            if want_tangent:
                scale = u2_e / ve if mean_dilatation else 0.0
                for na in range(nen):
                    for i in range(3):
                        for nb in range(nen):
                            for k in range(3):
                                if i <= k:
                                    v = kb[i, k, na, nb]
                                else:  # the tangent's symmetry: A_iJkL = A_kLiJ
                                    v = kb[k, i, nb, na]
                                blocks[e, 3 * na + i, 3 * nb + k] = v + scale * b[na, i] * b[nb, k]
            for n in range(nen):
                for i in range(3):
                    e_rows[e * nen + n, i] = fe[n, i]
            e_energy[e] = energy
    total = 0.0
    inverted = False
    for e in range(m):
        total += e_energy[e]
        inverted = inverted or jmin[e] <= 0.0
    gather_rows(e_rows, ptr, rows, forces)
    if inverted:
        return -1.0
    return total


@njit(cache=True, nogil=True, inline="always")
def _deformation(x, nodes, dn_e, fq, finv, det) -> float:
    """One element's deformation gradients F = sum_a x_a (x) dN_a (nq, 3, 3) into fq,
    their inverses into finv and det F (nq,) into det, at node positions x (n, 3) mm of
    its `nodes` (nen,) with reference gradients dn_e (nq, nen, 3) 1/mm; returns the
    smallest det F."""
    nq, nen = dn_e.shape[0], dn_e.shape[1]
    lo = 1e300
    for q in range(nq):
        for i in range(3):
            for jj in range(3):
                s = 0.0
                for n in range(nen):
                    s += x[nodes[n], i] * dn_e[q, n, jj]
                fq[q, i, jj] = s
        det[q] = _inverse(fq[q], finv[q])
        lo = min(lo, det[q])
    return lo


@njit(cache=True, nogil=True, inline="always")
def _add_point_forces(dn_q, finv_q, jq, w, u1, p_iso, fe, b) -> None:
    """One quadrature point's share (weight w, mm^3) of the element forces fe (nen, 3)
    mN, with P = P_iso + U' J F^-T (kPa; U' = u1), and of the volume gradient b
    (nen, 3) mm^2, J F^-T dN; dn_q (nen, 3) 1/mm, finv_q F^-1, jq det F."""
    nen = dn_q.shape[0]
    for n in range(nen):
        for i in range(3):
            s = 0.0
            g = 0.0
            for jj in range(3):
                cof = jq * finv_q[jj, i]
                s += (p_iso[i, jj] + u1 * cof) * dn_q[n, jj]
                g += cof * dn_q[n, jj]
            fe[n, i] += w * s
            b[n, i] += w * g


@njit(cache=True, nogil=True, inline="always")
def _add_point_tangent(dn_q, w, a, gt, ga, kb) -> None:
    """Add one quadrature point's share (weight w, mm^3) of the element tangent,
    w dN_aJ A_iJkL dN_bL (mN/mm), into kb [i, k, a, b] for i <= k only (the rest is
    its transpose); dn_q (nen, 3) 1/mm, a (9, 9) kPa indexed (3 i + J, 3 k + L); gt
    (3, nen) and ga (nen, 3) scratch. The innermost loops run over the nodes b along
    contiguous rows, which the compiler vectorizes: 2.5 times faster than the
    contraction over J innermost with every (i, k) computed."""
    nen = dn_q.shape[0]
    for n in range(nen):
        for ll in range(3):
            gt[ll, n] = dn_q[n, ll]
    for i in range(3):
        for k in range(i, 3):
            for na in range(nen):
                for ll in range(3):
                    s = 0.0
                    for jj in range(3):
                        s += dn_q[na, jj] * a[3 * i + jj, 3 * k + ll]
                    ga[na, ll] = w * s
            for na in range(nen):
                g0, g1, g2 = ga[na, 0], ga[na, 1], ga[na, 2]
                for nb in range(nen):
                    kb[i, k, na, nb] += g0 * gt[0, nb] + g1 * gt[1, nb] + g2 * gt[2, nb]


@njit(cache=True, nogil=True, inline="always")
def _add_volumetric_moduli(finv_q, jq, u1, u2, mean_dilatation, a) -> None:
    """Add to the moduli a (9, 9) kPa, indexed (3 i + J, 3 k + L), U' d2J/dF2 (U' = u1,
    kPa) and, without mean dilatation, U'' cof (x) cof (U'' = u2, kPa), cof = J F^-T;
    finv_q is F^-1 and jq det F at the point. Only the blocks k >= i (`isochoric`)."""
    for i in range(3):
        for jj in range(3):
            r = 3 * i + jj
            for k in range(i, 3):
                for ll in range(3):
                    c = 3 * k + ll
                    a[r, c] += (
                        u1 * jq * (finv_q[jj, i] * finv_q[ll, k] - finv_q[ll, i] * finv_q[jj, k])
                    )
                    if not mean_dilatation:
                        a[r, c] += u2 * jq * jq * finv_q[jj, i] * finv_q[ll, k]


@njit(cache=True, nogil=True)
def mean_dilatation(
    x: np.ndarray, conn: np.ndarray, dn: np.ndarray, wq: np.ndarray, volumes: np.ndarray
) -> np.ndarray:
    """(m,) each element's volume ratio det F averaged over its volume (mm^3 / mm^3);
    the line search's check of every trial step (4x faster than the einsum it replaced
    on the default Fruit)."""
    m, nq, nen = dn.shape[0], dn.shape[1], dn.shape[2]
    out = np.empty(m)
    for e in range(m):
        acc = 0.0
        for q in range(nq):
            f00 = f01 = f02 = f10 = f11 = f12 = f20 = f21 = f22 = 0.0
            for n in range(nen):
                p = conn[e, n]
                g0, g1, g2 = dn[e, q, n, 0], dn[e, q, n, 1], dn[e, q, n, 2]
                f00 += x[p, 0] * g0
                f01 += x[p, 0] * g1
                f02 += x[p, 0] * g2
                f10 += x[p, 1] * g0
                f11 += x[p, 1] * g1
                f12 += x[p, 1] * g2
                f20 += x[p, 2] * g0
                f21 += x[p, 2] * g1
                f22 += x[p, 2] * g2
            acc += wq[e, q] * (
                f00 * (f11 * f22 - f12 * f21)
                - f01 * (f10 * f22 - f12 * f20)
                + f02 * (f10 * f21 - f11 * f20)
            )
        out[e] = acc / volumes[e]
    return out
