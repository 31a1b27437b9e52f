"""A fill-reducing order of a tangent's rows found on its nodes instead of its dofs.

A FEM tangent's rows come in runs with one pattern: the free dofs of a node couple to
the same dofs. METIS on the graph of those runs (a ninth of the dof graph's entries on a
3D body) orders the nodes, and each node's rows follow in their own order: PARDISO takes
that as a user permutation (iparm[4] = 1, `pardiso.node_order`) instead of ordering the
dof graph itself. Runs are rows with identical column sets, whatever made them, so any
symmetric matrix gets a valid order (one row per run where no two rows are alike).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _runs(indptr, indices):
    """(B + 1,) the first row of each run of consecutive rows with the same columns."""
    n = indptr.shape[0] - 1
    starts = np.empty(n + 1, np.int64)
    starts[0] = 0
    b = 0
    for r in range(n - 1):
        a0, a1, c0 = indptr[r], indptr[r + 1], indptr[r + 1]
        same = a1 - a0 == indptr[r + 2] - c0
        q = 0
        while same and q < a1 - a0:
            same = indices[a0 + q] == indices[c0 + q]
            q += 1
        if not same:
            b += 1
            starts[b] = r + 1
    b += 1
    starts[b] = n
    return starts[: b + 1]


@njit(cache=True, nogil=True)
def _run_graph(indptr, indices, starts):
    """(indptr, indices) int32 of the runs' graph, upper triangle and diagonal: run b's
    first row's columns mapped to their runs from b on, each once (columns are sorted, so
    one run's columns are adjacent)."""
    n = indptr.shape[0] - 1
    runs = starts.shape[0] - 1
    run_of = np.empty(n, np.int64)
    for b in range(runs):
        for r in range(starts[b], starts[b + 1]):
            run_of[r] = b
    out_ptr = np.zeros(runs + 1, np.int32)
    out_idx = np.empty(indptr[n], np.int32)
    k = 0
    for b in range(runs):
        last = -1
        r = starts[b]
        for q in range(indptr[r], indptr[r + 1]):
            c = run_of[indices[q]]
            if c >= b and c != last:
                out_idx[k] = c
                k += 1
                last = c
        out_ptr[b + 1] = k
    return out_ptr, out_idx[:k]


def row_runs(indptr: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(B + 1,) the first row of each run of consecutive rows with the same columns of a
    symmetric matrix's full pattern (CSR, sorted columns), then the row count."""
    return _runs(indptr, indices)


def run_graph(
    indptr: np.ndarray, indices: np.ndarray, starts: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(indptr, indices) int32: the upper triangle (diagonal included) of the graph whose
    vertices are the runs `starts` (`row_runs`) of the full pattern (indptr, indices)."""
    return _run_graph(indptr, indices, starts)


def expand(order: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """(n,) int32 the rows in their new order: the rows of run order[0], then those of run
    order[1], ... (`order` (B,) the runs in their new order; PARDISO's perm convention:
    row i of the permuted matrix is row perm[i] of the original)."""
    sizes = np.diff(starts)[order]
    first = np.repeat(starts[:-1][order], sizes)
    within = np.arange(len(first)) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    return (first + within).astype(np.int32)
