"""C libraries' messages kept off the terminal: CHOLMOD (through cholespy) prints its
warnings with C's stdio, past Python's sys.stdout and sys.stderr, so they are caught at
file descriptors 1 and 2 and handed back as text for the caller to judge."""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
import tempfile
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Iterator


class Captured:
    """What a C library wrote to fd 1 or 2 inside `captured_output` (`text`, after the
    block)."""

    text: str = ""


def _flush_c_stdio() -> None:
    """fflush(NULL): C's buffered output goes out before the descriptors change back."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def captured_output() -> Iterator[Captured]:
    """Redirect fds 1 and 2 to a temporary file for the block; yields a Captured whose
    `text` holds what was written there. Python's own streams are flushed first, so
    nothing of ours is caught."""
    out = Captured()
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 1)
        os.dup2(tmp.fileno(), 2)
        try:
            yield out
        finally:
            _flush_c_stdio()
            for fd, copy in zip((1, 2), saved, strict=True):
                os.dup2(copy, fd)
                os.close(copy)
            tmp.seek(0)
            out.text = tmp.read().decode("utf-8", "replace")
