"""MKL PARDISO called directly (ctypes) for the factor the tangent solvers keep as CG's
preconditioner; the library is the one pip's `mkl` installs with pypardiso (the optional
extra `pardiso`: `pip install 'fruit-touch[pardiso]'`; `available` is False without it).

Why not pypardiso's `solve`: on every call it compares the whole matrix with the one it
factorized and converts its index arrays to one-based int32, and MKL's default of two
iterative-refinement steps per solve triples the cost of a solve that only
preconditions CG. The symbolic analysis is kept: `refactor` redoes only the numerical
factorization of a matrix with the same pattern. MKL runs on one thread (see
`_functions`) unless the process asks for more (`use_threads`, `fruit --solver-threads`).
On the default Fruit (`python tests/performance/bench_fem.py --factor`, one thread, rows
ordered on the nodes as the solvers do, `node_order`; Intel Xeon, 2026-12-07):

| | linear tets, 6,762 dofs | quadratic, 44,403 dofs |
|---|---|---|
| analysis + factorization | 43 ms | 0.81 s |
| numerical refactorization | 11 ms | 0.44 s |
| one solve | 0.88 ms | 26 ms |
| the same in single precision | 30 ms, 8 ms, 0.62 ms | 0.56 s, 0.24 s, 14 ms |

Matrices are the upper triangle of a symmetric matrix in CSR with sorted indices,
zero-based (iparm[34] = 1); the factor is float64, or float32 with `single` (both
solvers' CG preconditioner, `factorize_probed`; `linsolve.SINGLE_PRECISION`).
"""

from __future__ import annotations

import ctypes
import glob
import logging
import os
import sys
from typing import TYPE_CHECKING, Protocol

import numpy as np

from fruitcli.errors import SolverError
from fruitcli.fem import threads

if TYPE_CHECKING:
    import scipy.sparse as sp

SPD, SYMMETRIC_INDEFINITE = 2, -2  # PARDISO's mtype
_LOG = logging.getLogger(__name__)
MKL_THREADING_SEQUENTIAL = 1  # mkl_set_threading_layer: INTEL 0, SEQUENTIAL 1, GNU 3
MKL_THREADING_INTEL = 0

_THREADS = [1]  # PARDISO's threads asked for in this process (`use_threads`)
_LAYER: list[int | None] = [None]  # MKL's threading layer, once MKL is loaded


def use_threads(threads: int) -> None:
    """Run PARDISO's factorizations and solves on `threads` threads in this process, from
    before MKL is loaded (the threading layer is chosen then: 1, the default, MKL's
    sequential one). With more than one, MKL's OpenMP layer factors and solves in
    parallel: on a quiet 2-core Intel Xeon a refactorization of the quadratic default
    Fruit took 0.11 s instead of 0.21, and a single-precision solve 5 ms instead of 10 on
    one day but no less than on one thread on another (the docs' performance page),
    but the sums' order then changes from call to call, so results vary between runs
    within the solver's tolerances (on one thread they are the same to the last bit).
    A worker process (`multiprocessing`) keeps one thread: its parent's workers share the
    cores. Where the OpenMP layer is not installed, one thread, with a warning.
    RuntimeError once MKL is loaded on its sequential layer and more are asked for."""
    if threads < 1:
        raise ValueError(f"PARDISO threads: expected 1 or more, got {threads}")
    if _LAYER[0] == MKL_THREADING_SEQUENTIAL and threads > 1:
        raise RuntimeError("PARDISO threads: MKL is already loaded on one thread")
    _THREADS[0] = threads


def threads_used() -> int:
    """PARDISO's threads in this process: `use_threads`'s; one in a worker process or
    once MKL is loaded on its sequential layer."""
    if threads.in_worker_process() or _LAYER[0] == MKL_THREADING_SEQUENTIAL:
        return 1
    return _THREADS[0]


def _choose_layer(lib: ctypes.CDLL) -> None:
    """Set MKL's threading layer before its first call: the sequential one, or the OpenMP
    one when `threads_used` is above 1 and its libraries load (else a warning and one
    thread). MKL's global thread count is then 1; a PARDISO call asks for its own
    (`Pardiso._call`). The OpenMP threads sleep at once after each call (KMP_BLOCKTIME
    0, unless the user set it): spinning, they took the cores from numba's loops."""
    layer = MKL_THREADING_SEQUENTIAL
    if threads_used() > 1:
        if _openmp_layer_loads(lib):
            os.environ.setdefault("KMP_BLOCKTIME", "0")
            layer = MKL_THREADING_INTEL
        else:
            _LOG.warning(
                "PARDISO: MKL's OpenMP threading layer (mkl_intel_thread, libiomp5) is not "
                "installed beside MKL: one thread"
            )
    try:
        got = lib.MKL_Set_Threading_Layer(ctypes.c_int(layer))
        if layer == MKL_THREADING_INTEL and got != layer:  # MKL was initialised before
            _LOG.warning("PARDISO: MKL was loaded before fruit chose its threads: one thread")
            layer = MKL_THREADING_SEQUENTIAL
        if layer == MKL_THREADING_INTEL:
            lib.MKL_Set_Dynamic(ctypes.c_int(0))  # the threads asked, not fewer
        lib.MKL_Set_Num_Threads(ctypes.c_int(1))
    except AttributeError:  # an MKL without these functions: as it is
        layer = MKL_THREADING_SEQUENTIAL
    _LAYER[0] = layer


def _openmp_layer_loads(lib: ctypes.CDLL) -> bool:
    """True when MKL's OpenMP threading layer of the same version as the runtime library
    `lib` lies beside it (libmkl_intel_thread.so.3 beside libmkl_rt.so.3;
    mkl_intel_thread.2.dll beside mkl_rt.2.dll) and Intel's OpenMP runtime (libiomp5)
    there loads: MKL ends the process when it cannot load the layer it was told to use.
    (The layer itself loads only through MKL's runtime, which brings its core.)"""
    path = str(getattr(lib, "_name", ""))
    folder, name = os.path.split(path)
    if "mkl_rt" not in name:
        return False
    omp = [
        os.path.join(folder, f)
        for f in ("libiomp5.so", "libiomp5md.dll", "libiomp5.dylib")
        if os.path.exists(os.path.join(folder, f))
    ]
    layer = os.path.join(folder, name.replace("mkl_rt", "mkl_intel_thread"))
    if not omp or not os.path.exists(layer):
        return False
    try:
        ctypes.CDLL(omp[0], mode=ctypes.RTLD_GLOBAL)
    except OSError:
        return False
    return True


class PardisoError(SolverError):
    """PARDISO returned an error code (`code`, see ERRORS) or perturbed a pivot (a
    singular matrix: `singular` is True for that and for zero pivots). A SolverError:
    what reaches the user is its one line."""

    def __init__(self, message: str, code: int = 0):
        super().__init__(message)
        self.code = code

    @property
    def singular(self) -> bool:
        return self.code in (0, -4, -7)


ERRORS = {
    -1: "inconsistent input",
    -2: "not enough memory",
    -3: "reordering problem",
    -4: "zero pivot (the matrix is not positive definite or is singular)",
    -5: "unclassified internal error",
    -6: "reordering failed",
    -7: "the diagonal matrix is singular",
    -8: "32-bit integer overflow",
    -9: "not enough memory for out-of-core",
    -10: "out-of-core files",
    -11: "out-of-core read/write",
    -12: "wrong library (pardiso_64)",
}
"""PARDISO's error codes (MKL's documentation of `pardiso`)."""


_FUNCTIONS = None
_MISSING = False  # the library could not be loaded (asked once)


def _library():
    """MKL's runtime library: the one pip's `mkl` (pypardiso's dependency) puts in the
    environment's lib/, else wherever pypardiso finds it (its search globs the whole
    installation: 0.35 s)."""
    here = sorted(glob.glob(os.path.join(sys.prefix, "lib", "libmkl_rt.so*")), key=len)
    for path in here:
        try:
            return ctypes.CDLL(path)
        except OSError:
            continue
    import pypardiso

    return pypardiso.PyPardisoSolver().libmkl


def _functions():
    """(pardiso, pardisoinit, the library) of MKL's runtime library, loaded once."""
    global _FUNCTIONS
    if _FUNCTIONS is None:
        lib = _library()
        # MKL on one thread by default: numba's parallel element loops own the cores.
        # Beside them, MKL's OpenMP threads (Intel's runtime, or GNU's shared with numba)
        # spinning between calls made the p1 tangent products about 60 % slower and a p2
        # state 15-20 % slower on this 2-core machine; one thread also makes the factor's
        # sums the same from run to run (`use_threads` asks for more)
        _choose_layer(lib)
        i32 = ctypes.POINTER(ctypes.c_int32)
        pardiso = lib.pardiso
        pardiso.argtypes = [
            ctypes.POINTER(ctypes.c_int64),
            i32,
            i32,
            i32,
            i32,
            i32,
            ctypes.c_void_p,
            i32,
            i32,
            i32,
            i32,
            i32,
            i32,
            ctypes.c_void_p,
            ctypes.c_void_p,
            i32,
        ]
        pardiso.restype = None
        init = lib.pardisoinit
        init.argtypes = [ctypes.POINTER(ctypes.c_int64), i32, i32]
        init.restype = None
        _FUNCTIONS = pardiso, init, lib
    return _FUNCTIONS


def available() -> bool:
    """True when MKL's library can be loaded (the answer is kept)."""
    global _MISSING
    if _MISSING:
        return False
    try:
        _functions()
    except (ImportError, OSError, AttributeError):
        _MISSING = True
        return False
    return True


class Pardiso:
    """A PARDISO factorization of the symmetric matrix whose upper triangle (CSR) is
    `upper`, of type `mtype` (SPD or SYMMETRIC_INDEFINITE), in double precision or, with
    `single`, in single precision (half the memory to read per solve; a solve then
    leaves a relative residual of about 1e-4 on the default Fruit's linear tets and 5e-4
    on its quadratic ones: a preconditioner, not a solver). `order`: the rows' fill-reducing
    order (PARDISO's perm: row i of the factored matrix is row order[i]; None: METIS's
    on the matrix, PARDISO's default); with `order_only`, only the analysis runs and
    `perm` holds METIS's order. Raises PardisoError."""

    def __init__(
        self,
        upper: sp.csr_matrix,
        mtype: int = SPD,
        single: bool = False,
        order: np.ndarray | None = None,
        order_only: bool = False,
    ):
        self._pardiso, init, self._lib = _functions()
        self.threads = threads_used()
        self.n = upper.shape[0]
        self.mtype = mtype
        self.single = single
        self.dtype = np.float32 if single else np.float64
        self.indptr = np.ascontiguousarray(upper.indptr, dtype=np.int32)
        self.indices = np.ascontiguousarray(upper.indices, dtype=np.int32)
        self.data = np.ascontiguousarray(upper.data, dtype=self.dtype)
        self.pt = np.zeros(64, np.int64)
        self.iparm = np.zeros(64, np.int32)
        self._alive = False
        init(
            self._ptr(self.pt, ctypes.c_int64),
            ctypes.byref(ctypes.c_int32(mtype)),
            self._ptr(self.iparm),
        )
        self.iparm[7] = 0  # no iterative refinement: the solves precondition CG
        self.iparm[27] = 1 if single else 0  # precision of the factor and the solves
        self.iparm[34] = 1  # zero-based indices
        self.perm = None if order is None else np.ascontiguousarray(order, dtype=np.int32)
        if self.perm is not None:
            self.iparm[4] = 1  # the fill-reducing order is `order`, not PARDISO's METIS
        elif order_only:
            self.perm = np.zeros(self.n, np.int32)
            self.iparm[4] = 2  # the analysis writes its order into `perm`
        self._alive = True
        try:
            self._factor(11 if order_only else 12)
        except PardisoError:
            self.free()  # a failed factor's memory now, not when collected
            raise

    def same_pattern(self, upper: sp.csr_matrix) -> bool:
        """True when `upper` has this factor's sparsity pattern (then `refactor` applies)."""
        return (
            upper.shape[0] == self.n
            and len(upper.indices) == len(self.indices)
            and np.array_equal(upper.indptr, self.indptr)
            and np.array_equal(upper.indices, self.indices)
        )

    def refactor(self, upper: sp.csr_matrix) -> None:
        """Numerical factorization of `upper` (same pattern) on the kept analysis."""
        self.data = np.ascontiguousarray(upper.data, dtype=self.dtype)
        self._factor(22)

    def _factor(self, phase: int) -> None:
        """Numerical factorization (with the analysis for phase 12); a pivot PARDISO had
        to perturb (iparm[13], indefinite type) means a singular matrix here."""
        self._call(phase, self.data, np.zeros(self.n, self.dtype), np.zeros(self.n, self.dtype))
        if self.iparm[13] > 0:
            raise PardisoError(
                f"PARDISO: the matrix is singular ({self.iparm[13]} perturbed pivots)", 0
            )

    def solve(self, b: np.ndarray) -> np.ndarray:
        """x (float64) with A x = b for b (n,) or (n, k)."""
        b = np.asarray(b)
        rhs = np.asfortranarray(b.reshape(self.n, -1), dtype=self.dtype)
        x = np.zeros_like(rhs, order="F")
        self._call(33, self.data, rhs, x, nrhs=rhs.shape[1])
        return x.reshape(b.shape).astype(np.float64, copy=False)

    def free(self) -> None:
        """Release MKL's memory of this factor (it lives outside Python's heap)."""
        if self._alive:
            self._alive = False
            self._call(-1, self.data, np.zeros(1, self.dtype), np.zeros(1, self.dtype))

    def __del__(self):
        try:
            self.free()
        except Exception:
            pass

    @staticmethod
    def _ptr(a: np.ndarray, ctype: type[ctypes._SimpleCData] = ctypes.c_int32):
        return a.ctypes.data_as(ctypes.POINTER(ctype))

    def _call(
        self, phase: int, data: np.ndarray, b: np.ndarray, x: np.ndarray, nrhs: int = 1
    ) -> None:
        err = ctypes.c_int32(0)
        one = ctypes.c_int32(1)
        before = None
        if self.threads > 1:  # over any per-thread limit (threadpoolctl's, `threads`)
            before = self._lib.MKL_Set_Num_Threads_Local(ctypes.c_int(self.threads))
        try:
            self._call_pardiso(phase, data, b, x, nrhs, err, one)
        finally:
            if before is not None:
                self._lib.MKL_Set_Num_Threads_Local(ctypes.c_int(before))
        if err.value != 0:
            meaning = ERRORS.get(err.value, "unknown error")
            raise PardisoError(f"PARDISO phase {phase}: {meaning} (error {err.value})", err.value)

    def _call_pardiso(
        self,
        phase: int,
        data: np.ndarray,
        b: np.ndarray,
        x: np.ndarray,
        nrhs: int,
        err: ctypes.c_int32,
        one: ctypes.c_int32,
    ) -> None:
        self._pardiso(
            self._ptr(self.pt, ctypes.c_int64),
            ctypes.byref(one),
            ctypes.byref(one),
            ctypes.byref(ctypes.c_int32(self.mtype)),
            ctypes.byref(ctypes.c_int32(phase)),
            ctypes.byref(ctypes.c_int32(self.n)),
            data.ctypes.data,
            self._ptr(self.indptr),
            self._ptr(self.indices),
            None if self.perm is None else self._ptr(self.perm),
            ctypes.byref(ctypes.c_int32(nrhs)),
            self._ptr(self.iparm),
            ctypes.byref(ctypes.c_int32(0)),
            b.ctypes.data,
            x.ctypes.data,
            ctypes.byref(err),
        )


_LAST_ORDER: list[tuple[np.ndarray, np.ndarray, np.ndarray | None]] = []


def node_order(k: sp.csr_matrix) -> np.ndarray | None:
    """The rows' fill-reducing order (PARDISO's perm) of the symmetric k (CSR, both
    triangles, sorted columns) found on its nodes (`node_order.py`: METIS, PARDISO's own,
    on the graph of the runs of rows with one pattern), kept for the last pattern seen.
    None when no two rows are alike or PARDISO cannot order the runs' graph (then PARDISO
    orders the rows itself). On the quadratic default Fruit (44,403 dofs, 14,801 runs) the
    order, the analysis and the first factorization took 0.55-0.56 s instead of 0.60-0.62
    s, and the factor has 18.0 M entries instead of 18.4 M (the docs' performance page)."""
    import scipy.sparse as sp

    from fruitcli.fem.solver.node_order import expand, row_runs, run_graph

    for indptr, indices, order in _LAST_ORDER:
        if np.array_equal(indptr, k.indptr) and np.array_equal(indices, k.indices):
            return order
    starts = row_runs(k.indptr, k.indices)
    order = None
    runs = len(starts) - 1
    if runs < k.shape[0]:
        graph_ptr, graph_idx = run_graph(k.indptr, k.indices, starts)
        graph = sp.csr_matrix((np.ones(len(graph_idx)), graph_idx, graph_ptr), (runs, runs))
        try:
            ordering = Pardiso(graph, SPD, order_only=True)
        except PardisoError:
            pass
        else:
            assert ordering.perm is not None
            order = expand(ordering.perm, starts)
            ordering.free()
    _LAST_ORDER[:] = [(k.indptr.copy(), k.indices.copy(), order)]
    return order


def factorize_upper(
    upper: sp.csr_matrix,
    previous: Pardiso | None = None,
    single: bool = False,
    indefinite: bool = False,
    full: sp.csr_matrix | None = None,
) -> Pardiso:
    """A Pardiso factor of the symmetric matrix with upper triangle `upper`, in single
    precision with `single`: the numerical refactorization of `previous` (as its type)
    when it has the same pattern and precision (and is indefinite, with `indefinite`);
    otherwise a new one, positive definite first, then indefinite. Straight to the
    indefinite type (one analysis instead of two: 0.8-1.4 s each on a quadratic sphere
    of 6,327 tets) with `indefinite` (the caller knows the matrix is not positive
    definite), when `previous` was indefinite, or when its positive definite
    refactorization met a non-positive pivot (then no ordering makes it positive
    definite). `previous` is spent either way (freed unless returned). A new analysis
    orders the rows on their nodes (`node_order`) when the whole matrix `full` (CSR,
    sorted columns) is given, else by PARDISO's METIS on the rows. Raises PardisoError."""
    if previous is not None:
        known = previous.mtype == SYMMETRIC_INDEFINITE or not indefinite
        if known and previous.single == single and previous.same_pattern(upper):
            try:
                previous.refactor(upper)
                return previous
            except PardisoError as exc:
                indefinite = indefinite or previous.mtype == SYMMETRIC_INDEFINITE or exc.code == -4
        indefinite = indefinite or previous.mtype == SYMMETRIC_INDEFINITE
        previous.free()  # before the new analysis: two p2 factors would double the peak
    message, code = "", 0
    for mtype in (SYMMETRIC_INDEFINITE,) if indefinite else (SPD, SYMMETRIC_INDEFINITE):
        try:
            return Pardiso(upper, mtype, single, None if full is None else node_order(full))
        except PardisoError as exc:  # its message only: the exception would keep the
            message, code = str(exc), exc.code  # failed factor alive through its frame
    raise PardisoError(message, code)


SINGLE_PROBE = 0.1
"""Largest relative residual of a single-precision factor's solve of the probe (a
vector of ones: the smoothest load, where the factor's relative error is largest) for
it to precondition CG (2e-2 on the quadratic default Fruit at rest, 1e-4 with linear
tets); a double-precision factor must reach DOUBLE_PROBE."""

DOUBLE_PROBE = 1e-6


class Solves(Protocol):
    """A factor: anything with `solve(b)`."""

    def solve(self, b: np.ndarray) -> np.ndarray: ...


def passes_probe(k: sp.spmatrix | sp.sparray, fac: Solves, bound: float) -> bool:
    """True when fac's solve of a vector of ones is finite and leaves a relative residual
    of at most `bound` on the sparse k (any factor with `.solve`)."""
    probe = np.ones(k.shape[0])
    sol = fac.solve(probe)
    return bool(
        np.isfinite(sol).all() and np.linalg.norm(k @ sol - probe) <= bound * np.linalg.norm(probe)
    )


def factorize_probed(
    k: sp.spmatrix | sp.sparray,
    upper: sp.csr_matrix,
    previous: Pardiso | None = None,
    single: bool = False,
    indefinite: bool = False,
) -> Pardiso | None:
    """A factor of the symmetric k (sparse, upper its upper triangle) that passes its
    probe solve: single precision first when `single`, then double. None when the
    double-precision factor misses its probe (the caller's fallback takes over); a
    PardisoError of the double-precision factorization propagates. `previous` is spent
    and `indefinite` passed on (see `factorize_upper`, which orders a new analysis on k's
    nodes when k is CSR in canonical form); a single-precision factor found indefinite
    makes the double-precision one indefinite at once."""
    full = k if getattr(k, "format", None) == "csr" and k.has_canonical_format else None
    for precision in (True, False) if single else (False,):
        try:
            fac = factorize_upper(upper, previous, precision, indefinite, full)
        except PardisoError:
            if not precision:
                raise
            indefinite = indefinite or (previous is not None and previous.mtype != SPD)
            previous = None  # spent; double precision next
            continue
        previous = None
        indefinite = indefinite or fac.mtype == SYMMETRIC_INDEFINITE
        if passes_probe(k, fac, SINGLE_PROBE if precision else DOUBLE_PROBE):
            return fac
        fac.free()
    return None
