"""Ctrl-C held back while a C++ extension runs: a KeyboardInterrupt raised inside a
nanobind call (manifold3d) aborts the whole process ("terminate called after throwing
an instance of 'nanobind::python_error'", exit -6). Inside `deferred_sigint()` SIGINT is
noted and raised as KeyboardInterrupt once the block ends."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator


@contextlib.contextmanager
def deferred_sigint() -> Iterator[None]:
    """Hold SIGINT back for the block (main thread only; elsewhere a no-op), then raise
    KeyboardInterrupt if one came."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: came.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if came:
        raise KeyboardInterrupt


def ignore_sigpipe() -> None:
    """Ignore SIGPIPE again, as Python does at start-up. gmsh's initialize resets it to
    the default (terminate the process), so a later write to a closed pipe, such as a
    dead worker process's, would kill this process instead of raising BrokenPipeError.
    Call it after `gmsh.initialize` (main thread; elsewhere a no-op)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGPIPE, signal.SIG_IGN)
