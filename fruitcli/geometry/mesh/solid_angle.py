"""Signed solid angles of triangle soups: exact sums and a Barnes-Hut tree (numba).

The generalized winding number of a surface at q is the signed solid angle it subtends
there over 4 pi (Jacobson, Kavan and Sorkine-Hornung 2013). One triangle (a, b, c) seen
from q subtends (van Oosterom and Strackee 1983), with a, b, c taken relative to q,

    tan(omega / 2) = a . (b x c) / (|a||b||c| + (a.b)|c| + (b.c)|a| + (c.a)|b|),

positive when q sees the triangle's front (counter-clockwise) side from behind, so that
a closed outward surface gives 4 pi inside and 0 outside.

Far from a cluster of triangles its solid angle is the integral of n . g(x) dA with
g(x) = (x - q) / |x - q|^3, expanded about the cluster's area-weighted centre p
(Barill, Dickson, Schmidt, Levin and Jacobson 2018, to second order):

    sum_i N_i g_i + sum_ij M_ij dg_i/dx_j + 1/2 sum_ijk T_ijk d2g_i/dx_j dx_k,

with N = sum of vector areas A n, M_ij = sum A n_i (c - p)_j over the triangles
(centroids c), T_ijk = sum of the integrals of n_i (x - p)_j (x - p)_k dA. The tree
is a bounding-volume hierarchy of median splits; a node is expanded when q is farther
than `beta` times its radius from its centre, else its children (or, at a leaf, its
triangles exactly) are visited.

Coordinates are float64 in any unit (mm in fruit); results are solid angles over 4 pi.
"""

from __future__ import annotations

import numpy as np
from numba import njit

LEAF_TRIANGLES = 8
"""A tree node with at most this many triangles is a leaf (evaluated exactly)."""

# per-node record: centre (3), radius, N (3), tr M, sym M (6: xx yy zz xy xz yz),
# u = 2 a + c (3), cubic C(r) = sum T_ijk r_i r_j r_k (10: xxx yyy zzz xxy xxz yyx yyz
# zzx zzy xyz)
_NODE_FIELDS = 27


@njit(cache=True, nogil=True)
def _triangle_angle(px, py, pz, t, k):
    """Signed solid angle (sr) of triangle k of `t` (m, 9) seen from (px, py, pz)."""
    ax, ay, az = t[k, 0] - px, t[k, 1] - py, t[k, 2] - pz
    bx, by, bz = t[k, 3] - px, t[k, 4] - py, t[k, 5] - pz
    cx, cy, cz = t[k, 6] - px, t[k, 7] - py, t[k, 8] - pz
    la = np.sqrt(ax * ax + ay * ay + az * az)
    lb = np.sqrt(bx * bx + by * by + bz * bz)
    lc = np.sqrt(cx * cx + cy * cy + cz * cz)
    det = ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
    den = (
        la * lb * lc
        + (ax * bx + ay * by + az * bz) * lc
        + (bx * cx + by * cy + bz * cz) * la
        + (cx * ax + cy * ay + cz * az) * lb
    )
    return 2.0 * np.arctan2(det, den)


@njit(cache=True, nogil=True)
def _exact_kernel(t, points, out):
    for i in range(points.shape[0]):
        s = 0.0
        for k in range(t.shape[0]):
            s += _triangle_angle(points[i, 0], points[i, 1], points[i, 2], t, k)
        out[i] = s / (4.0 * np.pi)


def exact_winding(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Winding numbers (k,) at `points` (k, 3): every triangle for every point."""
    t = _soup(vertices, faces)
    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(pts))
    if len(pts) and len(t):
        _exact_kernel(t, pts, out)
    return out


def _soup(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Triangle corners (m, 9) float64, contiguous."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    return np.ascontiguousarray(v[f].reshape(-1, 9))


@njit(cache=True, nogil=True)
def _build_tree(cent, leaf):
    """Median splits along the longest side of the centroids' box, depth first.

    Returns (perm: triangle order, start, end: each node's range in that order, child:
    first child's id, the second is child + 1, -1 at a leaf). Parents precede children.
    """
    m = cent.shape[0]
    cap = 4 * (m // leaf + 1) + 1
    start = np.empty(cap, np.int64)
    end = np.empty(cap, np.int64)
    child = np.full(cap, -1, np.int64)
    perm = np.arange(m)
    stack = np.empty(256, np.int64)
    start[0], end[0] = 0, m
    n_nodes = 1
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        nd = stack[top]
        s, e = start[nd], end[nd]
        if e - s <= leaf:
            continue
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for q in range(s, e):
            for d in range(3):
                x = cent[perm[q], d]
                lo[d] = min(lo[d], x)
                hi[d] = max(hi[d], x)
        ax = 0
        for d in range(1, 3):
            if hi[d] - lo[d] > hi[ax] - lo[ax]:
                ax = d
        sub = perm[s:e].copy()
        key = np.empty(e - s)
        for q in range(e - s):
            key[q] = cent[sub[q], ax]
        perm[s:e] = sub[np.argsort(key)]
        mid = (s + e) // 2
        c = n_nodes
        n_nodes += 2
        child[nd] = c
        start[c], end[c] = s, mid
        start[c + 1], end[c + 1] = mid, e
        stack[top] = c
        stack[top + 1] = c + 1
        top += 2
    return perm, start[:n_nodes], end[:n_nodes], child[:n_nodes]


@njit(cache=True, nogil=True)
def _node_records(t, start, end, child):
    """Each node's centre, radius and expansion coefficients (n, _NODE_FIELDS), children
    first (moments shifted to the parent's centre), radii exact over the corners."""
    va, area, cen, quad = _triangle_moments(t)
    centre, big_n, big_m, big_t = _node_moments(start, end, child, va, area, cen, quad)
    return _pack_records(t, start, end, centre, big_n, big_m, big_t)


@njit(cache=True, nogil=True)
def _triangle_moments(t):
    """Per triangle of t (m, 9) mm: vector area A n (m, 3), area (m,), centroid (m, 3)
    and second moment about the centroid per area (m, 3, 3)."""
    m = t.shape[0]
    va = np.zeros((m, 3))  # vector areas A n
    area = np.zeros(m)
    cen = np.zeros((m, 3))
    quad = np.zeros((m, 3, 3))  # int (x - c)(x - c)^T dA / A = sum_v (v - c)(v - c)^T / 12
    for k in range(m):
        e1x, e1y, e1z = t[k, 3] - t[k, 0], t[k, 4] - t[k, 1], t[k, 5] - t[k, 2]
        e2x, e2y, e2z = t[k, 6] - t[k, 0], t[k, 7] - t[k, 1], t[k, 8] - t[k, 2]
        va[k, 0] = 0.5 * (e1y * e2z - e1z * e2y)
        va[k, 1] = 0.5 * (e1z * e2x - e1x * e2z)
        va[k, 2] = 0.5 * (e1x * e2y - e1y * e2x)
        area[k] = np.sqrt(va[k, 0] ** 2 + va[k, 1] ** 2 + va[k, 2] ** 2)
        for d in range(3):
            cen[k, d] = (t[k, d] + t[k, 3 + d] + t[k, 6 + d]) / 3.0
        for j in range(3):
            for kk in range(3):
                s = 0.0
                for v in range(3):
                    s += (t[k, 3 * v + j] - cen[k, j]) * (t[k, 3 * v + kk] - cen[k, kk])
                quad[k, j, kk] = s / 12.0
    return va, area, cen, quad


@njit(cache=True, nogil=True)
def _node_moments(start, end, child, va, area, cen, quad):
    """Per tree node, children first: its area-weighted centre (n, 3) and the moments of
    its triangles' vector areas about it, of order 0 (n, 3), 1 (n, 3, 3), 2 (n, 3, 3, 3)."""
    n = start.shape[0]
    centre = np.zeros((n, 3))
    tot = np.zeros(n)
    big_n = np.zeros((n, 3))
    big_m = np.zeros((n, 3, 3))
    big_t = np.zeros((n, 3, 3, 3))
    delta = np.zeros(3)
    for nd in range(n - 1, -1, -1):
        if child[nd] < 0:
            a = 0.0
            for k in range(start[nd], end[nd]):
                a += area[k]
                for d in range(3):
                    centre[nd, d] += area[k] * cen[k, d]
            for d in range(3):
                if a > 0.0:
                    centre[nd, d] /= a
                else:
                    s = 0.0
                    for k in range(start[nd], end[nd]):
                        s += cen[k, d]
                    centre[nd, d] = s / (end[nd] - start[nd])
            tot[nd] = a
            for k in range(start[nd], end[nd]):
                for d in range(3):
                    delta[d] = cen[k, d] - centre[nd, d]
                for i in range(3):
                    big_n[nd, i] += va[k, i]
                    for j in range(3):
                        big_m[nd, i, j] += va[k, i] * delta[j]
                        for kk in range(3):
                            big_t[nd, i, j, kk] += va[k, i] * (
                                delta[j] * delta[kk] + quad[k, j, kk]
                            )
        else:
            lft, rgt = child[nd], child[nd] + 1
            a = tot[lft] + tot[rgt]
            tot[nd] = a
            for d in range(3):
                if a > 0.0:
                    centre[nd, d] = (tot[lft] * centre[lft, d] + tot[rgt] * centre[rgt, d]) / a
                else:
                    centre[nd, d] = 0.5 * (centre[lft, d] + centre[rgt, d])
            for c in (lft, rgt):
                for d in range(3):
                    delta[d] = centre[c, d] - centre[nd, d]
                for i in range(3):
                    big_n[nd, i] += big_n[c, i]
                    for j in range(3):
                        big_m[nd, i, j] += big_m[c, i, j] + big_n[c, i] * delta[j]
                        for kk in range(3):
                            big_t[nd, i, j, kk] += (
                                big_t[c, i, j, kk]
                                + big_m[c, i, j] * delta[kk]
                                + big_m[c, i, kk] * delta[j]
                                + big_n[c, i] * delta[j] * delta[kk]
                            )
    return centre, big_n, big_m, big_t


@njit(cache=True, nogil=True)
def _pack_records(t, start, end, centre, big_n, big_m, big_t):
    """The records (n, _NODE_FIELDS): centre, radius exact over the node's corners, and
    the expansion coefficients from the moments."""
    n = start.shape[0]
    rec = np.zeros((n, _NODE_FIELDS))
    for nd in range(n):
        r2 = 0.0
        for k in range(start[nd], end[nd]):
            for v in range(3):
                dd = 0.0
                for d in range(3):
                    dd += (t[k, 3 * v + d] - centre[nd, d]) ** 2
                r2 = max(r2, dd)
        mm = big_m[nd]
        tt = big_t[nd]
        rec[nd, 0:3] = centre[nd]
        rec[nd, 3] = np.sqrt(r2)
        rec[nd, 4:7] = big_n[nd]
        rec[nd, 7] = mm[0, 0] + mm[1, 1] + mm[2, 2]
        rec[nd, 8], rec[nd, 9], rec[nd, 10] = mm[0, 0], mm[1, 1], mm[2, 2]
        rec[nd, 11], rec[nd, 12], rec[nd, 13] = (
            mm[0, 1] + mm[1, 0],
            mm[0, 2] + mm[2, 0],
            mm[1, 2] + mm[2, 1],
        )
        for k in range(3):  # u_k = 2 sum_i T_iik + sum_j T_kjj
            rec[nd, 14 + k] = (
                2.0 * (tt[0, 0, k] + tt[1, 1, k] + tt[2, 2, k])
                + tt[k, 0, 0]
                + tt[k, 1, 1]
                + tt[k, 2, 2]
            )
        for i in range(3):  # the cubic's coefficients: T summed over permutations
            for j in range(3):
                for k in range(3):
                    rec[nd, 17 + _cubic_slot(i, j, k)] += tt[i, j, k]
    return rec


@njit(cache=True, nogil=True)
def _cubic_slot(i, j, k):
    """Slot (0..9) of the monomial r_i r_j r_k: xxx yyy zzz xxy xxz yyx yyz zzx zzy xyz."""
    nx = (i == 0) + (j == 0) + (k == 0)
    ny = (i == 1) + (j == 1) + (k == 1)
    nz = 3 - nx - ny
    if nx == 3:
        return 0
    if ny == 3:
        return 1
    if nz == 3:
        return 2
    if nx == 2:
        return 3 if ny == 1 else 4
    if ny == 2:
        return 5 if nx == 1 else 6
    if nz == 2:
        return 7 if nx == 1 else 8
    return 9


@njit(cache=True, nogil=True)
def _fast_kernel(t, start, end, child, rec, beta, points, out):
    stack = np.empty(256, np.int64)
    b2 = beta * beta
    for i in range(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        s = 0.0
        stack[0] = 0
        top = 1
        while top > 0:
            top -= 1
            nd = stack[top]
            x = rec[nd, 0] - px  # r = centre - q
            y = rec[nd, 1] - py
            z = rec[nd, 2] - pz
            d2 = x * x + y * y + z * z
            if d2 > b2 * rec[nd, 3] * rec[nd, 3]:
                inv2 = 1.0 / d2
                inv3 = inv2 / np.sqrt(d2)
                inv5 = inv3 * inv2
                s += (x * rec[nd, 4] + y * rec[nd, 5] + z * rec[nd, 6]) * inv3
                rmr = (
                    rec[nd, 8] * x * x
                    + rec[nd, 9] * y * y
                    + rec[nd, 10] * z * z
                    + rec[nd, 11] * x * y
                    + rec[nd, 12] * x * z
                    + rec[nd, 13] * y * z
                )
                s += rec[nd, 7] * inv3 - 3.0 * rmr * inv5
                ru = x * rec[nd, 14] + y * rec[nd, 15] + z * rec[nd, 16]
                cub = (
                    rec[nd, 17] * x * x * x
                    + rec[nd, 18] * y * y * y
                    + rec[nd, 19] * z * z * z
                    + rec[nd, 20] * x * x * y
                    + rec[nd, 21] * x * x * z
                    + rec[nd, 22] * y * y * x
                    + rec[nd, 23] * y * y * z
                    + rec[nd, 24] * z * z * x
                    + rec[nd, 25] * z * z * y
                    + rec[nd, 26] * x * y * z
                )
                s += 0.5 * (-3.0 * ru * inv5 + 15.0 * cub * inv5 * inv2)
            elif child[nd] < 0:
                for k in range(start[nd], end[nd]):
                    s += _triangle_angle(px, py, pz, t, k)
            else:
                stack[top] = child[nd]
                stack[top + 1] = child[nd] + 1
                top += 2
        out[i] = s / (4.0 * np.pi)


class SolidAngleTree:
    """Barnes-Hut evaluation of one triangle soup's winding number (vertices (n, 3),
    faces (m, 3)); `beta`: a node is expanded only beyond beta times its radius."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, beta: float = 2.0):
        t = _soup(vertices, faces)
        self.beta = float(beta)
        if len(t) == 0:
            self.t = t
            return
        cent = (t[:, 0:3] + t[:, 3:6] + t[:, 6:9]) / 3.0
        perm, self.start, self.end, self.child = _build_tree(cent, LEAF_TRIANGLES)
        self.t = np.ascontiguousarray(t[perm])
        self.rec = _node_records(self.t, self.start, self.end, self.child)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """Winding numbers (k,) at `points` (k, 3)."""
        pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.zeros(len(pts))
        if len(pts) and len(self.t):
            _fast_kernel(self.t, self.start, self.end, self.child, self.rec, self.beta, pts, out)
        return out
