"""`fruit` as installed without the optional PARDISO extra, for comparing the linear
solver paths on one machine: MKL PARDISO is reported unavailable
(`fruitcli.fem.solver.pardiso.available`), so the FEM's factors are SciPy's SuperLU's
(quadratic elements) and cholespy's (the paper's linear ones).

Run: .venv/bin/python tests/performance/without_pardiso.py SUBCOMMAND [ARGS]...
(the arguments of `fruit`).
"""

from fruitcli.cli.main import main
from fruitcli.fem.solver import pardiso

if __name__ == "__main__":
    pardiso._MISSING = True  # what `available` keeps when MKL cannot be loaded
    main()
