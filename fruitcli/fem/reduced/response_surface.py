"""Polynomial response surfaces over a box of chamber pressures (kPa).

A pressure vector p (K,) in the box [lo, hi] is scaled to xi in [-1, 1]^K, and an
output y(p) is a sum of products of Legendre polynomials, one per chamber, of total
degree <= d: y = phi(xi) @ C with phi (M,) and C (M, outputs). Legendre products keep
the least-squares fit well conditioned where plain monomials of a box far from zero
are not. The design points are a Chebyshev-Lobatto tensor grid (the box's corners,
edges and centre included), visited in snake order so that consecutive points differ
in one chamber's pressure by one grid step.
"""

from __future__ import annotations

import itertools

import numpy as np


def exponents(k: int, degree: int) -> np.ndarray:
    """(M, k) Legendre degrees per chamber of every product of total degree <= degree,
    sorted by total degree (the constant first)."""
    rows = [e for e in itertools.product(range(degree + 1), repeat=k) if sum(e) <= degree]
    rows.sort(key=lambda e: (sum(e), tuple(-v for v in e)))
    return np.array(rows, dtype=np.int64).reshape(-1, k)


def scale(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Pressures (..., K) kPa to xi in [-1, 1] on the box [lo, hi]."""
    return (2.0 * np.asarray(p, float) - (lo + hi)) / (hi - lo)


def legendre_table(xi: np.ndarray, degree: int) -> np.ndarray:
    """(degree + 1, ...) Legendre polynomials P_0..P_degree at xi (...) by their
    three-term recurrence."""
    xi = np.asarray(xi, float)
    out = np.empty((degree + 1, *xi.shape))
    out[0] = 1.0
    if degree >= 1:
        out[1] = xi
    for n in range(1, degree):
        out[n + 1] = ((2 * n + 1) * xi * out[n] - n * out[n - 1]) / (n + 1)
    return out


def basis(xi: np.ndarray, exps: np.ndarray) -> np.ndarray:
    """(n, M) basis at scaled pressures xi (n, K) (or (M,) at one vector (K,))."""
    xi = np.asarray(xi, float)
    degree = int(exps.max()) if exps.size else 0
    table = legendre_table(xi, degree)  # (d+1, [n,] K)
    cols = np.arange(exps.shape[1])
    if xi.ndim == 1:
        return table[exps, cols].prod(axis=1)
    return table[exps, :, cols].prod(axis=1).T


def lobatto_points(n: int) -> np.ndarray:
    """n Chebyshev-Lobatto points in [-1, 1], increasing (n >= 2)."""
    return -np.cos(np.pi * np.arange(n) / (n - 1))


def snake_grid(k: int, n: int) -> np.ndarray:
    """(n**k, k) indices of the tensor grid, each row one step from the previous
    (boustrophedon order: the last axis runs back and forth)."""
    if k == 0:
        return np.zeros((1, 0), np.int64)
    rows = []
    for head in snake_grid(k - 1, n):
        flip = int(head.sum()) % 2 == 1
        for j in range(n - 1, -1, -1) if flip else range(n):
            rows.append([*head, j])
    return np.array(rows, dtype=np.int64)


def fit(phi: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least-squares coefficients C (M, outputs) of y (n, outputs) ~ phi (n, M) C."""
    coef, *_ = np.linalg.lstsq(phi, y, rcond=None)
    return coef


def leave_one_out(phi: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(n, outputs) leave-one-out residuals of the least-squares fit: each sample's
    misfit when the fit is made without it, r_i / (1 - h_ii) (exact for least squares;
    infinite where a sample alone fixes a coefficient)."""
    q, _ = np.linalg.qr(phi)
    residual = y - q @ (q.T @ y)
    h = np.einsum("ij,ij->i", q, q)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where((1.0 - h)[:, None] > 1e-10, residual / (1.0 - h)[:, None], np.inf)
