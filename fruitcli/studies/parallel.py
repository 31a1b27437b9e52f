"""Run independent study cases in worker processes, one progress callback, results in
the order of the cases (identical to a serial run)."""

from __future__ import annotations

import multiprocessing as mp
import os
from typing import Callable, Sequence


def default_jobs() -> int:
    return max(1, os.cpu_count() or 1)


def run_cases(func: Callable, cases: Sequence, jobs: int | None = None,
              progress: Callable[[int, int], None] | None = None) -> list:
    """`[func(c) for c in cases]`, spread over `jobs` processes (1: in this process)."""
    jobs = default_jobs() if jobs is None else max(1, int(jobs))
    results = [None] * len(cases)
    if jobs == 1 or len(cases) <= 1:
        for n, case in enumerate(cases):
            results[n] = func(case)
            if progress:
                progress(n + 1, len(cases))
        return results
    ctx = mp.get_context("spawn")
    with ctx.Pool(min(jobs, len(cases))) as pool:
        done = 0
        for n, value in pool.imap_unordered(_indexed, [(func, n, c) for n, c in
                                                       enumerate(cases)]):
            results[n] = value
            done += 1
            if progress:
                progress(done, len(cases))
    return results


def _indexed(args):
    func, n, case = args
    return n, func(case)
