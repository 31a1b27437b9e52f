"""Benchmark: MKL PARDISO on one thread and on two (`fruit --solver-threads N`) on the
default Fruit: a quadratic state from the previous one (its breathing and a sweep of c1)
and its first state from rest as `fruit simulate` solves it.

`bench_state.py` runs in a new process for each thread count (MKL's threading layer is
chosen when MKL loads), one thread then two, on one tetrahedral mesh built first (about
a minute). Each of its lines is printed with the thread count in front; the load
average is in each line (the gain needs an idle core: compare lines taken at a like
load). On more than one thread the states vary between runs within the solver's
tolerances.

Run: .venv/bin/python tests/performance/bench_solver_threads.py [--mesh DIR]
(--mesh DIR: keep the mesh there for later runs)
"""

import argparse
import os
import subprocess
import sys
import tempfile
from datetime import UTC, datetime
from pathlib import Path

HERE = Path(__file__).resolve().parent
MAX_RUNS = 1  # four runs of bench_state.py, about three minutes

KEPT = ("breathing:", "sweep:", "first state from rest, new folder")


def bench_state(mesh: Path, threads: int, first: bool) -> list[str]:
    """The lines of `bench_state.py --solver-threads threads [--first]` on the mesh in
    `mesh` that carry figures."""
    args = [sys.executable, str(HERE / "bench_state.py"), "--mesh", str(mesh)]
    args += ["--solver-threads", str(threads)] + (["--first"] if first else [])
    done = subprocess.run(args, capture_output=True, text=True, check=True)
    return [
        line for line in done.stdout.splitlines() if line.startswith(KEPT) and "medians" not in line
    ]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--mesh", type=Path, default=None, help="keep the mesh in this folder")
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    from run_all import commit, processor

    print(
        f"MKL PARDISO on one thread and two, default Fruit; "
        f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC, commit {commit()}, {processor()}, "
        f"{os.cpu_count()} cores",
        flush=True,
    )
    with tempfile.TemporaryDirectory() as tmp:
        mesh = args.mesh or Path(tmp)
        for threads in (1, 2):
            for first in (False, True):
                for line in bench_state(mesh, threads, first):
                    print(f"PARDISO on {threads} thread(s), {line}", flush=True)


if __name__ == "__main__":
    main()
