"""Parallel element loops whose nodal sums do not depend on the number of threads: the
elements are shared among the threads in BLOCKS blocks, each element writes its nodal
rows, and each node then adds its elements' rows in element order (`node_incidence`),
the order a serial scatter added them in; so the results are the same bits on one
thread and on many (a timing-dependent summation order once made a sweep's parallel
rows differ from its serial ones). Used by the corotational kernels
(`materials/corotation_kernels.py`) and the hyperelastic element loop
(`elements/integrate.py`)."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

BLOCKS = 64
"""Blocks of elements the parallel loops share among the threads (each block allocates
its scratch once; more blocks than threads balance uneven elements)."""


def node_incidence(tets: np.ndarray, n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """(ptr (n + 1,), rows (nen m,)) for elements tets (m, nen): node a's element rows
    e * nen + b (tets[e, b] == a) are rows[ptr[a]:ptr[a + 1]], in increasing e (the
    serial scatter's order)."""
    flat = np.ascontiguousarray(tets, dtype=np.int64).ravel()
    rows = np.argsort(flat, kind="stable").astype(np.int64)
    ptr = np.zeros(n_nodes + 1, np.int64)
    ptr[1:] = np.cumsum(np.bincount(flat, minlength=n_nodes))
    return ptr, rows


@njit(cache=True, nogil=True)
def n_blocks(m: int) -> int:
    """Blocks for m elements: BLOCKS, or fewer for a small mesh."""
    return max(1, min(m, BLOCKS))


@njit(cache=True, nogil=True, inline="always")
def block_range(c: int, nblocks: int, m: int) -> tuple[int, int]:
    """Element range [lo, hi) of block c of nblocks over m elements."""
    return c * m // nblocks, (c + 1) * m // nblocks


@njit(cache=True, nogil=True, parallel=True)
def gather_rows(e_rows: np.ndarray, ptr: np.ndarray, rows: np.ndarray, out: np.ndarray) -> None:
    """out[a, i] = sum of e_rows[rows[k], i] over node a's k in ptr[a]:ptr[a + 1], added in
    that (element) order; e_rows (nen m, 3), out (n, 3), ptr and rows from
    `node_incidence`."""
    for a in prange(ptr.shape[0] - 1):
        for i in range(3):
            s = 0.0
            for k in range(ptr[a], ptr[a + 1]):
                s += e_rows[rows[k], i]
            out[a, i] = s
