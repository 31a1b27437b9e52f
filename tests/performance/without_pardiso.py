"""`fruit` as installed without the optional PARDISO extra, for comparing the linear
solver paths on one machine: MKL PARDISO is reported unavailable
(`fruitcli.fem.solver.pardiso.available`), so the FEM's factors are cholespy's and
SciPy's SuperLU's. With FRUIT_BENCH_NO_CHOLESPY=1 in the environment, cholespy is left
out too (SuperLU only).

Run: .venv/bin/python tests/performance/without_pardiso.py SUBCOMMAND [ARGS]...
(the arguments of `fruit`).
"""

import os
import sys

from fruitcli.cli.main import main
from fruitcli.fem.solver import continuum_linsolve, linsolve, pardiso

if __name__ == "__main__":
    pardiso._MISSING = True  # what `available` keeps when MKL cannot be loaded
    if os.environ.get("FRUIT_BENCH_NO_CHOLESPY") == "1":
        linsolve._cholesky = continuum_linsolve._cholesky = None
    sys.exit(main())
