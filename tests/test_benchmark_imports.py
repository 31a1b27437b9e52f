"""The benchmark scripts start as `make bench` starts them: `python
tests/performance/NAME.py`, with only the script's own folder on the path. A script that
imports from the test suite (`tests.…`, at the top or inside a function) must put the
repository's root on the path itself, or it stops with ModuleNotFoundError. Nothing else
runs the benchmarks between `make bench` runs; their types are checked by mypy (`make
lint`)."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "tests" / "performance"


def imported_test_modules(path: Path) -> list[str]:
    """The `tests.…` modules a script imports anywhere in it."""
    tree = ast.parse(path.read_text())
    return sorted(
        {
            node.module
            for node in ast.walk(tree)
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("tests.")
        }
    )


SCRIPTS = [p for p in sorted(BENCHMARKS.glob("*.py")) if imported_test_modules(p)]


@pytest.mark.parametrize("script", SCRIPTS, ids=[p.stem for p in SCRIPTS])
def test_a_benchmark_finds_the_test_modules_it_imports(script: Path, tmp_path: Path):
    """The script's top level run as a script's (its folder first on the path, not the
    repository), then each `tests.…` module it imports anywhere imported."""
    code = (
        "import importlib, runpy, sys\n"
        f"sys.path[0] = {str(BENCHMARKS)!r}\n"
        f"runpy.run_path({str(script)!r}, run_name='benchmark_top_level')\n"
        f"for name in {imported_test_modules(script)!r}:\n"
        "    importlib.import_module(name)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"} | {"MPLBACKEND": "Agg"}
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr[-2000:]
