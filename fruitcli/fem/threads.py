"""Who uses the cores while the FEM solves: numba's parallel element loops
(`materials/corotation_kernels.py`, `elements/integrate.py`) on every core when no other
process keeps one busy, on one thread otherwise (`choose_element_threads`, when a
solver is made). The BLAS under numpy (OpenBLAS) is kept to one thread, and MKL's
PARDISO runs on one (`solver/pardiso.py`): their threads spin for a while after each
call, and beside numba's they took each other's cores (on the default Fruit at 4 mm,
11,000 dofs, where OpenBLAS starts threading its dot products, a breathing state took
92 ms instead of about 15).
"""

from __future__ import annotations

_DONE = False


def in_worker_process() -> bool:
    """True in a process started by `multiprocessing` (a sweep's, a study's or a curve's
    worker): its siblings share the cores, so it takes one (curves, PARDISO threads)."""
    import multiprocessing

    return multiprocessing.parent_process() is not None


def one_blas_thread() -> None:
    """Limit the BLAS libraries loaded in this process to one thread, from the first
    solver on and for the rest of the process (threadpoolctl, so it holds whether numpy
    was imported before fruit or not). fruit's other numpy work is small vectors and
    matrices (the reduced model's fit and products, the sensing's arrays), which BLAS
    threads do not speed up."""
    global _DONE
    if _DONE:
        return
    _DONE = True
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # declared in pyproject.toml; without it BLAS keeps its threads
        return
    threadpool_limits(limits=1, user_api="blas")


AUTO = True
"""Whether `choose_element_threads` picks the element loops' threads from what else runs
(the benchmarks turn it off to time a fixed number)."""

BUSY_CORES = 0.5
"""Other processes using more than this many cores (over SAMPLE_S) make the element
loops run on one thread."""

SAMPLE_S = 0.05
"""How long `others_busy_cores` watches the machine (s)."""

KEEP_S = 30.0
"""How long a choice of threads holds before the machine is watched again (s): a study
or a sweep makes many solvers, and each watch sleeps SAMPLE_S."""

_CHOICE = (-1e9, 0)  # (time.monotonic() of the last watch, threads chosen)


def others_busy_cores(window_s: float = SAMPLE_S) -> float | None:
    """Cores kept busy by other processes (and the host: steal time) over window_s,
    from /proc/stat minus this process's own CPU time; None where /proc/stat is missing.
    (The load average would count this process's own spinning threads.)"""
    import os
    import time

    def busy_ticks() -> int:
        with open("/proc/stat") as fh:
            v = [int(t) for t in fh.readline().split()[1:9]]
        return v[0] + v[1] + v[2] + v[5] + v[6] + v[7]  # user nice system irq softirq steal

    try:
        b0, t0 = busy_ticks(), os.times()
        time.sleep(window_s)
        b1, t1 = busy_ticks(), os.times()
    except (OSError, ValueError, IndexError):
        return None
    own = (t1.user + t1.system) - (t0.user + t0.system)
    busy = (b1 - b0) / os.sysconf("SC_CLK_TCK")
    return max(0.0, busy - own) / window_s


def choose_element_threads() -> int:
    """Set numba's threads for the element loops on this thread: every core when no
    other process keeps one busy, else one (watched at most every KEEP_S); return the
    number. numba's workers
    busy-wait between loops; with another process on a core they wait for it instead:
    a p1 breathing state took 37-56 ms on two threads against 16-22 ms on one beside a
    test run (on the idle machine two threads were 18-28 % faster). The threads never
    change the results (the loops sum in element order)."""
    import time

    import numba

    global _CHOICE
    if not AUTO:
        return numba.get_num_threads()
    if time.monotonic() - _CHOICE[0] > KEEP_S:
        others = others_busy_cores()
        busy = others is not None and others > BUSY_CORES
        # numba.config sets its options with setattr at import: its stubs do not list them
        all_cores = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
        _CHOICE = (time.monotonic(), 1 if busy else all_cores)
    numba.set_num_threads(_CHOICE[1])
    return _CHOICE[1]
