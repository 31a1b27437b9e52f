"""Pressure-volume curves followed in worker processes, one curve each at a time: the
curves of a body share nothing but its equilibrium under its weight (`limits.Start`),
so each runs on its own solver and gives what it gives in one process. `fruit limits`
(`limits_stage.follow_curves`) and the planner's `limits` stage
(`pressure_check.check_pressures` with `jobs`) use them."""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

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


def curve_label(names: Sequence[str], which: Any, direction: int) -> str:
    """A curve for progress: "chamber c1 inflation", "chambers together inflation"
    (`which` a chamber's index or the chambers' pressure ratios)."""
    what = "inflation" if direction > 0 else "suction"
    if isinstance(which, (int, np.integer)):
        return f"chamber {names[int(which)]} {what}"
    return f"chambers together {what}"


def run_curves(
    follow: Callable[[Any], Any],
    cases: Sequence[Any],
    labels: Sequence[str],
    jobs: int,
    progress: Callable[[str], None],
    why: str = "",
) -> list:
    """`[follow(c) for c in cases]` over `jobs` (> 1) worker processes, in the order
    given (start the longest first), saying each curve's label as it ends; `follow` is a
    module-level function."""
    from fruitcli.studies.executors import Task, open_executor, run_graph

    progress(f"limits: {len(cases)} curves in {jobs} worker processes{why}")
    done = 0

    def ended(key: int, result: Any) -> None:
        nonlocal done
        done += 1
        progress(f"limits: {labels[key]} followed ({done} of {len(cases)})")

    pool = open_executor(jobs)
    try:
        results = run_graph(pool, {k: Task(_call, (follow, c)) for k, c in enumerate(cases)}, ended)
    finally:
        pool.close()
    return [results[k] for k in range(len(cases))]


def _call(arg: tuple[Callable[[Any], Any], Any], deps: dict) -> Any:
    follow, case = arg
    return follow(case)
