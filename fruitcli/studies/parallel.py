"""Run independent study cases in worker processes or on a Dask cluster, one progress
callback, results in the order of the cases (identical to a serial run)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, TypeVar

from fruitcli.studies.executors import Task, default_jobs, open_executor, run_graph

if TYPE_CHECKING:
    from fruitcli.studies.executors import DaskPool, LocalPool, Serial

__all__ = ["CurveProcesses", "default_jobs", "run_cases"]

C = TypeVar("C")  # a case
R = TypeVar("R")  # its result


def run_cases(
    func: Callable[[C], R],
    cases: Sequence[C],
    jobs: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    scheduler: str | None = None,
    pool: Serial | LocalPool | DaskPool | None = None,
) -> list[R]:
    """`[func(c) for c in cases]`, spread over `jobs` processes (1: in this process), over
    the workers of the Dask `scheduler` at that address, or over an open `pool` (see
    `fruitcli.studies.executors.open_executor`). `func` is a module-level function."""
    if not cases:
        return []
    own = pool is None
    if pool is None:
        pool = open_executor(1 if len(cases) == 1 and not scheduler else jobs, scheduler)
    tasks = {n: Task(_call, (func, case)) for n, case in enumerate(cases)}
    done = 0

    def on_done(key: int, result: object):
        nonlocal done
        done += 1
        if progress:
            progress(done, len(cases))

    try:
        results = run_graph(pool, tasks, on_done)
    finally:
        if own:
            pool.close()
    return [results[n] for n in range(len(cases))]


def _call(arg: tuple[Callable[[C], R], C], deps: dict):
    func, case = arg
    return func(case)


class CurveProcesses:
    """Local worker processes for the FEM's pressure-volume curves
    (`fruitcli.fem.curve_workers.CurvePool`): `jobs` of them at most (None: every
    core)."""

    def __init__(self, jobs: int | None = None):
        self.jobs = jobs

    def map(
        self,
        follow: Callable[[C], R],
        cases: Sequence[C],
        labels: Sequence[str],
        workers: int,
        progress: Callable[[str], None],
    ) -> list[R]:
        """`[follow(c) for c in cases]` over `workers` processes, in the order given
        (start the longest first), saying each case's label as it ends."""
        progress(f"limits: {len(cases)} curves in {workers} worker processes")
        done = 0

        def ended(key: int, result: object) -> None:
            nonlocal done
            done += 1
            progress(f"limits: {labels[key]} followed ({done} of {len(cases)})")

        pool = open_executor(workers)
        try:
            tasks = {n: Task(_call, (follow, case)) for n, case in enumerate(cases)}
            results = run_graph(pool, tasks, ended)
        finally:
            pool.close()
        return [results[n] for n in range(len(cases))]
