"""Pressure-volume curves followed in worker processes, one curve each at a time: the
curves of a body share nothing but its equilibrium under its weight (`limits.Start`),
so each runs on its own solver and gives what it gives in one process. `fruit limits`
(`limits_stage.follow_curves`) and the planner's `limits` stage
(`pressure_check.check_pressures` with `jobs`) use them."""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Sequence
from typing import Any

WORKER_BYTES_PER_DOF = 15_000
"""Memory one worker takes per degree of freedom (bytes): the model, its tangent and the
sparse factor; on the default Fruit (50,990 dofs, PARDISO) a worker peaked at 740 MB."""


def curve_jobs(jobs: int | None, curves: int, dofs: int) -> tuple[int, str]:
    """(worker processes for `curves` curves, why fewer than asked): `jobs` (None: every
    core, or one in a process that is itself a worker, such as a sweep's), at most one
    per curve and as many as the memory available holds."""
    from fruitcli import memory
    from fruitcli.studies.executors import default_jobs

    if jobs is None:
        jobs = 1 if multiprocessing.parent_process() is not None else default_jobs()
    room = int(memory.SHARE * memory.available_bytes() // (WORKER_BYTES_PER_DOF * dofs))
    n = max(1, min(jobs, curves, room))
    why = "" if n >= min(jobs, curves) else f" (the memory available holds {max(room, 1)})"
    return n, why


def run_curves(
    follow: Callable[[Any], Any],
    cases: Sequence[Any],
    jobs: int,
    progress: Callable[[str], None],
    why: str = "",
) -> list:
    """`[follow(c) for c in cases]` over `jobs` (> 1) worker processes, in the order
    given (start the longest first); `follow` is a module-level function."""
    from fruitcli.studies.parallel import run_cases

    progress(f"limits: {len(cases)} curves in {jobs} worker processes{why}")
    return run_cases(
        follow, cases, jobs, lambda k, total: progress(f"limits: {k} of {total} curves followed")
    )
