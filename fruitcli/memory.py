"""Sizes estimated before they are allocated: a request that would not fit in the memory
available is one line with the estimate, not a process killed by the kernel."""

from __future__ import annotations

import os
from collections.abc import Callable

from fruitcli.errors import FruitError

SHARE = 0.8
"""Largest share of the available memory one allocation may plan to take."""


def available_bytes() -> int:
    """Memory available to a new allocation (bytes): MemAvailable on Linux, else the
    physical memory."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 2**63 - 1


def require(nbytes: float, what: str, error: Callable[[str], Exception] = FruitError) -> None:
    """Raise `error` naming `what` when `nbytes` exceeds SHARE of the available memory."""
    have = available_bytes()
    if nbytes > SHARE * have:
        raise error(f"{what} needs about {_size(nbytes)} of memory, {_size(have)} is available")


def _size(nbytes: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if nbytes < 1024 or unit == "TiB":
            return f"{nbytes:.1f} {unit}" if unit != "B" else f"{int(nbytes)} B"
        nbytes /= 1024
    return f"{nbytes:.1f} TiB"
