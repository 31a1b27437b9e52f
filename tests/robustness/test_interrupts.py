"""Ctrl-C is one line and exit 130 whatever was running, a compiled kernel included."""

import pytest


def _checkout_env() -> dict:
    """The environment of a child Python that imports this checkout's fruitcli."""
    import os
    from pathlib import Path

    import fruitcli

    return dict(os.environ, PYTHONPATH=str(Path(fruitcli.__file__).parents[1]))


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


def test_an_interrupted_console_command_runs_the_exit_functions_and_skips_finalization(
    tmp_path,
):
    """From the console (`main()`), an interrupted command prints one line, runs the
    exit functions (multiprocessing's clean-up is one) and ends with 130 without the
    interpreter's finalization: a module-level object's finalizer never runs."""
    import subprocess
    import sys

    code = (
        "import atexit\n"
        "from fruitcli.evaluation import report\n"
        "def interrupted(*args, **kwargs):\n"
        "    raise KeyboardInterrupt\n"
        "report.evaluate_pair = interrupted\n"
        "atexit.register(print, 'exit function')\n"
        "class Finalized:\n"
        "    def __del__(self):\n"
        "        print('finalized')\n"
        "kept = Finalized()\n"
        "from fruitcli.cli.main import main\n"
        "main()\n"
    )
    args = ["evaluate", "--truth", "t.csv", "--measured", "m.csv", "--out", str(tmp_path / "o")]
    done = subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=_checkout_env(),
    )
    # click ends the line a Ctrl-C interrupted (its "^C") before the message
    assert (done.returncode, done.stdout, done.stderr) == (
        130,
        "exit function\n",
        "\nInterrupted.\n",
    )


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


TAXELS = "id,i,j,x_mm,y_mm,z_mm\n0,0,0,0,0,0\n1,1,0,16,0,0\n2,0,1,0,12,0\n3,1,1,16,12,0\n"


def _fruit(args, cwd, **kwargs):
    import subprocess
    import sys

    return subprocess.Popen(
        [sys.executable, "-c", "from fruitcli.cli.main import main; main()", *args],
        cwd=cwd,
        env=_checkout_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
        **kwargs,
    )


@pytest.mark.parametrize("seconds", [1.0, 2.5, 4.0])
def test_ctrl_c_in_a_sweep_with_workers_is_one_line(tmp_path, seconds):
    """Ctrl-C reaches every process of the group (as from a terminal): the workers ignore
    it, the parent stops them and says "Interrupted." (exit 130), no worker's traceback.
    Whenever it comes: a sweep already finished exits 0."""
    import os
    import signal
    import time

    (tmp_path / "taxels.csv").write_text(TAXELS)
    (tmp_path / "s.toml").write_text(
        '[scene]\nname = "s"\n[grid]\ntaxels = "taxels.csv"\n[bench]\nstep_mm = 0.01\n'
        "reference_length_mm = 20.0\n"  # the sweep may end before Ctrl-C: it must succeed
    )
    args = ["sweep", "s.toml", "--set", "bench.seed=0,1,2,3,4,5", "--jobs", "2", "--out", "o"]
    proc = _fruit(args, tmp_path)
    time.sleep(seconds)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert proc.returncode in (0, 130), err
    if proc.returncode == 130:
        assert err.rstrip().splitlines()[-1] == "Interrupted."


def test_ctrl_c_at_the_last_instant_is_interrupted(tmp_path):
    """A Ctrl-C while the interpreter shuts down (after the command's work, in its exit
    functions) does not end the process by the signal: the command, done, exits 0 with
    what it printed, or says "Interrupted." with exit 130."""
    import subprocess
    import sys

    code = (
        "import atexit, os, signal, time\n"
        "atexit.register(lambda: (os.kill(os.getpid(), signal.SIGINT), time.sleep(1)))\n"
        "import sys; sys.argv = ['fruit', 'scenes']\n"
        "from fruitcli.cli.main import main; main()\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        env=_checkout_env(),
        capture_output=True,
        text=True,
    )
    assert (done.returncode, done.stderr) in ((0, ""), (130, "Interrupted.\n")), done
    assert "touchpad-4x4" in done.stdout  # what the command printed is kept
