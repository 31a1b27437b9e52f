"""Sparse assembly with a precomputed pattern: (m, d, d) element blocks (d = 3 nodes per
element: 12 for linear tets, 30 for quadratic) -> CSR over the free degrees of freedom,
by one compiled pass over the blocks adding each entry into its CSR slot (no sorting
at run time; in the blocks' order, so the sums are those of the bincount it replaced,
without its masked copy of every entry: 2-3 times faster on the quadratic Fruit)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numba import njit


def element_dofs(tets: np.ndarray) -> np.ndarray:
    """(m, 3 nen) global dof numbers 3 * node + component, node-major."""
    return (3 * tets[:, :, None] + np.arange(3)).reshape(len(tets), 3 * tets.shape[1])


@dataclass(frozen=True)
class CsrPattern:
    """Where each kept element-matrix entry lands in the CSR data of the free-dof matrix."""

    free: np.ndarray  # (n_free,) global dof numbers
    entry_slot: np.ndarray  # (m*d*d,) index into CSR data, -1: the entry is dropped
    diag_slot: np.ndarray  # (n_free,) CSR data index of each diagonal entry
    indptr: np.ndarray
    indices: np.ndarray

    @classmethod
    def build(cls, tets: np.ndarray, n_nodes: int, free_mask: np.ndarray) -> CsrPattern:
        """Pattern for dofs where `free_mask` (3 n_nodes,) is True."""
        free = np.flatnonzero(free_mask)
        new = np.full(3 * n_nodes, -1, dtype=np.int64)
        new[free] = np.arange(len(free))
        dofs = element_dofs(tets)
        d = dofs.shape[1]
        rows = new[np.repeat(dofs, d, axis=1)].ravel()
        cols = new[np.tile(dofs, (1, d))].ravel()
        keep = (rows >= 0) & (cols >= 0)
        n = len(free)
        diag = np.arange(n)
        r = np.concatenate([rows[keep], diag])
        c = np.concatenate([cols[keep], diag])
        key = r * n + c
        uniq, inverse = np.unique(key, return_inverse=True)
        ur, uc = uniq // n, uniq % n
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(ur, minlength=n), out=indptr[1:])
        n_kept = int(keep.sum())
        entry_slot = np.full(len(keep), -1, np.int32 if len(uniq) < 2**31 else np.int64)
        entry_slot[keep] = inverse[:n_kept]
        return cls(
            free=free,
            entry_slot=entry_slot,
            diag_slot=inverse[n_kept:],
            indptr=indptr,
            indices=uc.astype(np.int32),
        )

    @property
    def nnz(self) -> int:
        return len(self.indices)

    def assemble(self, blocks: np.ndarray, diagonal: np.ndarray | None = None) -> sp.csr_matrix:
        """CSR matrix from element blocks (m, d, d) plus an optional diagonal (n_free,)."""
        data = _scatter(
            np.ascontiguousarray(blocks, dtype=float).reshape(-1), self.entry_slot, self.nnz
        )
        if diagonal is not None:
            data[self.diag_slot] += diagonal
        n = len(self.free)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(n, n))


@njit(cache=True, nogil=True)
def _scatter(values, slots, nnz):
    """(nnz,) sums of values into their slots, in order (slot -1: dropped)."""
    out = np.zeros(nnz)
    for i in range(values.shape[0]):
        k = slots[i]
        if k >= 0:
            out[k] += values[i]
    return out
