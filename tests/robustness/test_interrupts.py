"""Ctrl-C is one line and exit 130 whatever was running, a compiled kernel included."""

import pytest


def test_a_kernel_interrupted_by_ctrl_c_is_one_line(monkeypatch, capsys, tmp_path):
    from fruitcli.cli.main import main
    from fruitcli.evaluation import report

    def kernel(*args, **kwargs):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:  # as numba's dispatcher reports a signal inside a kernel
            raise SystemError("<function> returned a result with an exception set") from None

    monkeypatch.setattr(report, "evaluate_pair", kernel)
    with pytest.raises(SystemExit) as done:
        main(["evaluate", "--truth", "t.csv", "--measured", "m.csv", "--out", str(tmp_path / "o")])
    assert done.value.code == 130
    assert capsys.readouterr().err == "Interrupted.\n"


def test_other_errors_still_show_their_traceback(monkeypatch, tmp_path):
    from fruitcli.cli.main import main
    from fruitcli.evaluation import report

    def broken(*args, **kwargs):
        raise SystemError("a real bug")

    monkeypatch.setattr(report, "evaluate_pair", broken)
    with pytest.raises(SystemError, match="a real bug"):
        main(["evaluate", "--truth", "t.csv", "--measured", "m.csv", "--out", str(tmp_path / "o")])


def test_ctrl_c_inside_a_deferred_block_comes_after_it():
    import os
    import signal

    from fruitcli.interrupts import deferred_sigint

    finished = []
    before = signal.getsignal(signal.SIGINT)  # Python's own, or the default in a background job
    with pytest.raises(KeyboardInterrupt):
        with deferred_sigint():
            os.kill(os.getpid(), signal.SIGINT)
            finished.append(sum(range(100_000)))  # the block runs to its end
    assert finished == [sum(range(100_000))]
    assert signal.getsignal(signal.SIGINT) == before


def test_check_layout_defers_ctrl_c(monkeypatch):
    import os
    import signal

    from fruitcli.fem.meshing import shells

    done = []

    def layout(outer, chambers, where):
        os.kill(os.getpid(), signal.SIGINT)
        done.append(True)

    monkeypatch.setattr(shells, "_check_layout", layout)
    with pytest.raises(KeyboardInterrupt):
        shells.check_layout({}, [], "s.toml")
    assert done == [True]


def _ignored(signum: int) -> bool:
    """Whether the kernel ignores `signum` for this process (/proc/self/status SigIgn)."""
    from pathlib import Path

    status = Path("/proc/self/status").read_text()
    mask = int(status.split("SigIgn:")[1].split()[0], 16)
    return bool(mask >> (signum - 1) & 1)


def test_gmsh_leaves_sigpipe_ignored():
    """gmsh.initialize resets SIGPIPE to terminate the process; a later write to a dead
    worker's pipe then killed the test run (make: Error 141) instead of raising
    BrokenPipeError. occ_mesh.start ignores it again."""
    import signal

    from fruitcli.electrostatics import occ_mesh

    gmsh = occ_mesh.start("sigpipe-check")
    try:
        assert _ignored(signal.SIGPIPE)
    finally:
        gmsh.finalize()
    assert _ignored(signal.SIGPIPE)
