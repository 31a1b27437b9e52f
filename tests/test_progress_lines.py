"""Progress that says what it measures: a solved state's line and its time left, and
numba's compiles announced once."""

from __future__ import annotations

import subprocess
import sys
from types import SimpleNamespace

from fruitcli import compile_notice
from fruitcli.fem.stage import state_line
from tests.conftest import ROOT


def test_state_line_names_its_figures_and_the_time_left():
    res = SimpleNamespace(iterations=1, solve_ms=2500.0, residual=4.9e-7, kept=False)
    assert state_line(0, 3, [9000.0], res) == (
        "state 1/3: equilibrium after 1 Newton iteration in 2.5 s (relative force residual 4.9e-07)"
    )
    # a first state taken from the one an earlier run kept in the folder says so
    kept = SimpleNamespace(iterations=0, solve_ms=500.0, residual=4.9e-7, kept=True)
    assert state_line(0, 3, [500.0], kept) == (
        "state 1/3: equilibrium kept from an earlier run (pressure-check.npz), after 0 Newton "
        "iterations in 0.5 s (relative force residual 4.9e-07)"
    )
    # after the second state: the mean of the states after the first, times those left
    res = SimpleNamespace(iterations=4, solve_ms=3000.0, residual=1e-7, kept=False)
    assert state_line(2, 13, [9000.0, 1000.0, 3000.0], res) == (
        "state 3/13: equilibrium after 4 Newton iterations in 3.0 s "
        "(relative force residual 1.0e-07); about 20 s left for 10 more"
    )
    assert "left" not in state_line(12, 13, [9000.0] + [1000.0] * 12, res)


def _event(start: bool):
    return SimpleNamespace(is_start=start)


def test_notice_says_the_first_compile_once_and_counts_kernels_not_nested_compiles():
    said = []
    notice = compile_notice.Notice(said.append)
    for start in (True, True, False, False, True, False):  # a kernel calling one, then one
        notice.on_event(_event(start))
    assert said == [compile_notice.ANNOUNCE]
    notice.summary()
    assert said[1].startswith("compiled 2 kernel(s) in ") and said[1].endswith(
        " s; later runs load them from numba's cache"
    )
    quiet = compile_notice.Notice(said.append)
    quiet.silent = True
    quiet.on_event(_event(True))
    quiet.on_event(_event(False))
    quiet.summary()
    assert len(said) == 2


def test_a_compile_after_numba_is_imported_is_announced(tmp_path):
    """In a fresh interpreter: the listener installed before numba's import hears a
    kernel compiled (no disk cache), and nothing when no kernel compiles."""
    code = (
        "from fruitcli import compile_notice as c\n"
        "said = []\n"
        "c.install(said.append)\n"
        "import numba\n"
        "{body}"
        "print(said)\n"
    )
    compiled = "numba.njit(lambda x: x + 1)(1)\n"
    for body, expect in ((compiled, [compile_notice.ANNOUNCE]), ("", [])):
        out = subprocess.run(
            [sys.executable, "-c", code.format(body=body)],
            capture_output=True,
            text=True,
            cwd=ROOT,
            check=True,
            env={"PYTHONPATH": str(ROOT), "NUMBA_CACHE_DIR": str(tmp_path)},
        )
        assert out.stdout.strip() == repr(expect)


def test_time_left_at_the_rate_since_the_first_mark():
    from fruitcli.time_left import time_left

    assert time_left((10.0, 100), 300, 1000, now=14.0) == "; about 14 s left"  # 50/s
    assert time_left(None, 300, 1000) == ""
    assert time_left((10.0, 100), 100, 1000, now=14.0) == ""  # no rate yet
    assert time_left((10.0, 100), 1000, 1000, now=14.0) == ""  # done
