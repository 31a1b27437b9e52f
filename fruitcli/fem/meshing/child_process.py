"""gmsh in a child process: run in its own session so that a time limit or Ctrl-C can
kill it whole (gmsh can ignore polite signals for a long time), and ended with its
parent however the parent ends.

The parent calls `run_module`; the child's ``main`` calls `follow_parent` first.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

PARENT_ENV = "FRUIT_GMSH_PARENT"
"""Environment variable holding the parent's process id."""
PARENT_POLL_S = 0.5


def run_module(module: str, args: list[str], time_limit_s: float) -> tuple[int, str]:
    """Run ``python -m module args`` in its own session, with this package importable
    and this process as its parent; -> (exit code, stderr text). TimeoutError when it
    is still running after `time_limit_s` seconds (it is killed, with its children)."""
    root = str(Path(__file__).resolve().parents[3])
    env = dict(
        os.environ,
        PYTHONPATH=os.pathsep.join([root, os.environ.get("PYTHONPATH", "")]),
        **{PARENT_ENV: str(os.getpid())},
    )
    proc = subprocess.Popen(
        [sys.executable, "-m", module, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
        env=env,
        text=True,
    )
    try:
        _, err = proc.communicate(timeout=time_limit_s)
    except subprocess.TimeoutExpired:
        kill_group(proc.pid)
        proc.communicate()
        raise TimeoutError(module) from None
    except BaseException:  # Ctrl-C or any error here: the child (own session) goes too
        kill_group(proc.pid)
        proc.communicate()
        raise
    return proc.returncode, err


def kill_group(pid: int) -> None:
    """SIGKILL a child's process group; one that has just ended is no error."""
    try:
        os.killpg(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def last_error_line(err: str, code: int) -> str:
    """The child's last stderr line, or its exit code when it said nothing."""
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    return lines[-1] if lines else f"exit code {code}"


def follow_parent() -> None:
    """In the child: end with the parent named by `PARENT_ENV`, when set."""
    if os.environ.get(PARENT_ENV, "").isdigit():
        die_with_parent(int(os.environ[PARENT_ENV]))


def die_with_parent(parent_pid: int) -> None:
    """End this process when `parent_pid` ends, however it ends (SIGKILL included): on
    Linux the kernel sends SIGKILL (prctl PR_SET_PDEATHSIG); elsewhere, and for a parent
    gone before that call, a daemon thread polls the parent id (gmsh's C calls, made
    through ctypes, release the GIL, so the thread runs while gmsh meshes)."""
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(PARENT_POLL_S)
        os._exit(130)

    threading.Thread(target=watch, daemon=True, name="parent-watch").start()
