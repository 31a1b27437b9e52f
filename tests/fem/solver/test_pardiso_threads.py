"""MKL PARDISO on several threads (`pardiso.use_threads`, `fruit --solver-threads`): the
factor and its solves run with MKL's threads, to the same solution as SciPy's; a worker
process keeps one thread; bad requests get one line. Each case that loads MKL runs in a
fresh interpreter: the threading layer is chosen when MKL is first loaded."""

import subprocess
import sys
import textwrap

import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.fem.solver import pardiso

pytestmark = pytest.mark.skipif(not pardiso.available(), reason="MKL PARDISO not installed")


SPY = """
def spy_on_threads(pardiso):
    \"\"\"A list that gets MKL's max threads inside each PARDISO call from now on.\"\"\"
    seen = []
    call = pardiso.Pardiso._call_pardiso
    def spy(self, *args):
        seen.append(self._lib.MKL_Get_Max_Threads())
        return call(self, *args)
    pardiso.Pardiso._call_pardiso = spy
    return seen
"""


def run_python(code: str) -> str:
    """stdout of `code`, after `SPY`, run by this interpreter in a new process (fails on
    its errors)."""
    done = subprocess.run(
        [sys.executable, "-c", SPY + textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_two_threads_factor_and_solve_with_two_and_match_scipy():
    """With use_threads(2) before MKL is loaded, MKL runs each PARDISO call on 2 threads
    (its max threads read inside the calls), and the double-precision solve of a 3D
    Laplacian agrees with SciPy's to 1e-10."""
    out = run_python(
        """
        import numpy as np, scipy.sparse as sp, scipy.sparse.linalg as spla
        from fruitcli.fem.solver import pardiso
        from fruitcli.fem.solver.linsolve import upper_triangle
        pardiso.use_threads(2)
        seen = spy_on_threads(pardiso)
        one = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(16, 16))
        eye = sp.identity(16)
        k = (sp.kron(sp.kron(one, eye), eye) + sp.kron(sp.kron(eye, one), eye)
             + sp.kron(sp.kron(eye, eye), one)).tocsr()
        fac = pardiso.factorize_upper(upper_triangle(k))
        b = np.random.default_rng(1).standard_normal(k.shape[0])
        ref = spla.spsolve(k.tocsc(), b)
        err = np.abs(fac.solve(b) - ref).max() / np.abs(ref).max()
        print(fac.threads, ",".join(map(str, sorted(set(seen)))), err < 1e-10)
        """
    )
    assert out.split() == ["2", "2", "True"]


def test_a_worker_process_keeps_one_thread():
    """A process forked by multiprocessing from a parent whose PARDISO runs on two threads
    factors and solves on one (MKL's max threads read inside its calls): the workers
    share the cores."""
    out = run_python(
        """
        import multiprocessing
        import numpy as np, scipy.sparse as sp
        from fruitcli.fem.solver import pardiso
        from fruitcli.fem.solver.linsolve import upper_triangle
        seen = spy_on_threads(pardiso)
        k = upper_triangle((sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(50, 50))).tocsr())
        def factor_and_solve():
            seen.clear()
            pardiso.factorize_upper(k).solve(np.ones(50))
            return pardiso.threads_used(), sorted(set(seen))
        def in_worker(_):
            return factor_and_solve()
        if __name__ == "__main__":
            pardiso.use_threads(2)
            here = factor_and_solve()
            with multiprocessing.get_context("fork").Pool(1) as pool:
                there = pool.map(in_worker, [0])[0]
            print(here, there)
        """
    )
    assert out.strip() == "(2, [2]) (1, [1])"


def test_threads_asked_after_mkl_is_loaded_or_below_one_are_refused():
    """use_threads(0) is a ValueError; more than one thread once MKL is loaded on one is
    a RuntimeError; one thread then is fine."""
    out = run_python(
        """
        from fruitcli.fem.solver import pardiso
        try:
            pardiso.use_threads(0)
        except ValueError as exc:
            print("value:", exc)
        assert pardiso.available()
        pardiso.use_threads(1)
        try:
            pardiso.use_threads(2)
        except RuntimeError as exc:
            print("runtime:", exc)
        """
    )
    assert "value: PARDISO threads: expected 1 or more, got 0" in out
    assert "runtime: PARDISO threads: MKL is already loaded on one thread" in out


def test_the_cli_refuses_fewer_than_one_solver_thread():
    """`fruit --solver-threads 0 ...`: click's one usage line naming the option, exit 2."""
    result = CliRunner().invoke(cli, ["--solver-threads", "0", "scenes"])
    assert result.exit_code == 2
    assert "--solver-threads" in result.output
    assert "Traceback" not in result.output


def test_without_the_openmp_layer_pardiso_warns_and_keeps_one_thread():
    """Where MKL's OpenMP layer does not load, asking for two threads gives a warning
    naming it and a factor that runs on one (MKL's threads read inside its calls)."""
    out = run_python(
        """
        import logging, sys
        import numpy as np, scipy.sparse as sp
        logging.basicConfig(stream=sys.stdout, format="warning: %(message)s")
        from fruitcli.fem.solver import pardiso
        from fruitcli.fem.solver.linsolve import upper_triangle
        seen = spy_on_threads(pardiso)
        pardiso._openmp_layer_loads = lambda lib: False
        pardiso.use_threads(2)
        k = upper_triangle((sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(50, 50))).tocsr())
        fac = pardiso.factorize_upper(k)
        fac.solve(np.ones(50))
        print(fac.threads, pardiso.threads_used(), sorted(set(seen)))
        """
    )
    assert "warning: PARDISO: MKL's OpenMP threading layer" in out
    assert out.strip().splitlines()[-1] == "1 1 [1]"


def test_the_cli_hands_its_solver_threads_to_pardiso(monkeypatch):
    """`fruit --solver-threads 2 COMMAND` and `fruit COMMAND --solver-threads 2` ask
    PARDISO for two threads before the command runs; more threads than cores are capped
    at the cores; one thread asks for nothing; 0 after the command is refused too."""
    import os

    asked = []
    monkeypatch.setattr(pardiso, "use_threads", asked.append)
    cores = os.cpu_count() or 1
    for args in (
        ["--solver-threads", "2", "scenes"],
        ["scenes", "--solver-threads", "2"],
        ["--solver-threads", str(cores + 3), "scenes"],
        ["scenes", "--solver-threads", "1"],
    ):
        assert CliRunner().invoke(cli, args).exit_code == 0, args
    assert asked == [min(2, cores), min(2, cores), cores]
    late = CliRunner().invoke(cli, ["scenes", "--solver-threads", "0"])
    assert late.exit_code == 2
    assert "--solver-threads" in late.output
