"""Who uses the cores while the FEM solves: numba's parallel element loops
(`materials/corotation_kernels.py`). The BLAS under numpy (OpenBLAS) is kept to one
thread, and MKL's PARDISO runs on one (`solver/pardiso.py`): their threads spin for a
while after each call, and beside numba's they took each other's cores (on the default
Fruit at 4 mm, 11,000 dofs, where OpenBLAS starts threading its dot products, a
breathing state took 92 ms instead of about 15).
"""

from __future__ import annotations

_DONE = False


def one_blas_thread() -> None:
    """Limit the BLAS libraries loaded in this process to one thread (once; threadpoolctl,
    so it holds whether numpy was imported before fruit or not)."""
    global _DONE
    if _DONE:
        return
    _DONE = True
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # declared in pyproject.toml; without it BLAS keeps its threads
        return
    threadpool_limits(limits=1, user_api="blas")
