"""Pressure-volume curves followed in worker processes, one curve each at a time: the
curves of a body share nothing but its equilibrium under its weight
(`linear_response.Start`), so each runs on its own solver and gives what it gives in one
process. `fruit limits` (`limits_stage.follow_curves`) and the planner's `limits` stage
(`pressure_check.check_pressures`) take a `CurvePool` from their caller (the processes
themselves are `fruitcli.studies.parallel.CurveProcesses`, above this package)."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any, Protocol

import numpy as np

from fruitcli.fem import threads

WORKER_BYTES_PER_DOF = 15_000
"""Memory one worker takes per degree of freedom (bytes): the model, its tangent and the
sparse factor; on the default Fruit (50,990 dofs, PARDISO) a worker peaked at 740 MB."""


class CurvePool(Protocol):
    """Where curves may run: `jobs` worker processes (None: every core), and `map`,
    which runs `[follow(c) for c in cases]` over `workers` of them, in the order given,
    saying each case's label through `progress` as it ends."""

    jobs: int | None

    def map(
        self,
        follow: Callable[[Any], Any],
        cases: Sequence[Any],
        labels: Sequence[str],
        workers: int,
        progress: Callable[[str], None],
    ) -> list: ...


def curve_jobs(pool: CurvePool | None, curves: int, dofs: int) -> tuple[int, str]:
    """(worker processes for `curves` curves, why fewer than asked): none without a
    pool; the pool's jobs (None: every core, or one in a process that is itself a
    worker, such as a sweep's), at most one per curve and as many as the memory
    available holds."""
    from fruitcli import memory

    if pool is None:
        return 1, ""
    jobs = pool.jobs
    if jobs is None:
        jobs = 1 if threads.in_worker_process() else os.cpu_count() or 1
    room = int(memory.SHARE * memory.available_bytes() // (WORKER_BYTES_PER_DOF * dofs))
    n = max(1, min(jobs, curves, room))
    why = "" if n >= min(jobs, curves) else f" (the memory available holds {max(room, 1)})"
    return n, why


def curve_label(names: Sequence[str], which: Any, direction: int) -> str:
    """A curve for progress: "chamber c1 inflation", "chambers together inflation"
    (`which` a chamber's index or the chambers' pressure ratios)."""
    what = "inflation" if direction > 0 else "suction"
    if isinstance(which, (int, np.integer)):
        return f"chamber {names[int(which)]} {what}"
    return f"chambers together {what}"


def run_curves(
    pool: CurvePool,
    follow: Callable[[Any], Any],
    cases: Sequence[Any],
    labels: Sequence[str],
    order: Sequence[int],
    workers: int,
    why: str,
    progress: Callable[[str], None],
) -> list:
    """`[follow(c) for c in cases]` over `workers` of `pool`'s processes (`curve_jobs`,
    `why` fewer), started in `order` (indices into `cases`: the longest first), each
    case's label said as it ends; the results in the cases' own order."""
    if why:
        progress(f"limits: {workers} worker processes{why}")
    done = pool.map(
        follow, [cases[i] for i in order], [labels[i] for i in order], workers, progress
    )
    results: list = [None] * len(cases)
    for i, result in zip(order, done, strict=True):
        results[i] = result
    return results
