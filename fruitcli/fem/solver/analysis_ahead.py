"""PARDISO's analysis of a body's tangent made ahead, on a thread of its own, while the
model and its first tangent are built: the first factorization then only factors.

The pattern of a body's tangents is known once its free dofs are
(`assemble.CsrPattern`), before any tangent. `start` orders that pattern on its nodes
(`pardiso.node_order`) and runs PARDISO's analysis (phase 11, positive definite type)
on a thread; PARDISO's calls release the GIL, so the main thread goes on meanwhile.
`taken` hands the analysis to the next new factor of a matrix of that pattern
(`continuum_linsolve.factorize`), which then runs only the numerical factorization
(phase 22). A positive definite analysis reads only the pattern, so the factor is the
same to the last bit. On the quadratic default Fruit the order and analysis take 0.32 s
of the first factorization's 0.61 s (the docs' performance page has the timings).
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.fem.solver import pardiso

if TYPE_CHECKING:
    import scipy.sparse as sp

MIN_ROWS = 10_000
"""Rows from which `start` analyses a pattern ahead (below, the analysis takes a few
tens of milliseconds)."""

_PENDING: list[_Analysis] = []  # the analysis `start` began last, until taken


class _Analysis:
    """The order and analysis (positive definite, `single` precision) of the symmetric
    pattern (indptr, indices: CSR, both triangles, sorted columns), made on a thread;
    `factor` is the analysed Pardiso, or None when it failed."""

    def __init__(self, indptr: np.ndarray, indices: np.ndarray, single: bool):
        self.indptr, self.indices, self.single = indptr, indices, single
        self.factor: pardiso.Pardiso | None = None
        self.thread = threading.Thread(target=self._analyse, name="pardiso-analysis")
        self.thread.start()

    def _analyse(self) -> None:
        import scipy.sparse as sp

        n = len(self.indptr) - 1
        full = sp.csr_matrix((np.zeros(len(self.indices)), self.indices, self.indptr), (n, n))
        rows = np.repeat(np.arange(n), np.diff(self.indptr))
        kept = self.indices >= rows  # the upper triangle's entries
        upper_ptr = np.zeros(n + 1, np.int64)
        np.cumsum(np.bincount(rows[kept], minlength=n), out=upper_ptr[1:])
        upper = sp.csr_matrix((np.zeros(int(kept.sum())), self.indices[kept], upper_ptr), (n, n))
        try:  # the values are not read: a positive definite analysis takes the pattern
            order = pardiso.node_order(full)
            self.factor = pardiso.Pardiso(
                upper, pardiso.SPD, self.single, order, analysis_only=True
            )
        except Exception:  # nothing made: the factorization analyses as without it
            self.factor = None

    def fits(self, indptr: np.ndarray, indices: np.ndarray, single: bool) -> bool:
        """True for this pattern (CSR, both triangles) in this precision."""
        return (
            single == self.single
            and np.array_equal(indptr, self.indptr)
            and np.array_equal(indices, self.indices)
        )


def start(indptr: np.ndarray, indices: np.ndarray, single: bool) -> None:
    """Begin ordering and analysing the symmetric pattern (indptr, indices: CSR, both
    triangles, sorted columns), positive definite and in `single` precision, on a thread
    of its own, unless that analysis is already under way. An analysis begun before for
    another pattern or precision and not taken is dropped. Nothing below MIN_ROWS rows
    or without MKL PARDISO."""
    if _PENDING and _PENDING[-1].fits(indptr, indices, single):
        return
    taken(None, single)
    if len(indptr) - 1 >= MIN_ROWS and pardiso.available():
        _PENDING.append(_Analysis(indptr, indices, single))


def taken(k: sp.csr_matrix | None, single: bool) -> pardiso.Pardiso | None:
    """The analysis begun by `start`, once finished, when it is of k's pattern (CSR,
    sorted columns) in `single` precision; None otherwise (then it is freed, as with k
    None). Either way it is no longer pending."""
    if not _PENDING:
        return None
    analysis = _PENDING.pop()
    analysis.thread.join()
    factor = analysis.factor
    if factor is not None and k is not None and analysis.fits(k.indptr, k.indices, single):
        return factor
    if factor is not None:
        factor.free()
    return None
