"""Where and when a study or benchmark ran: the processor and a one-line stamp."""

from __future__ import annotations

import datetime
import importlib.metadata
import os
import platform
from pathlib import Path


def processor() -> str:
    """The processor's model name (Linux's /proc/cpuinfo), else what `platform` says."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_line() -> str:
    """Where and when a study ran: UTC date, fruitcli version, processor and cores."""
    date = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    try:
        version = importlib.metadata.version("fruitcli")
    except importlib.metadata.PackageNotFoundError:
        version = "(not installed)"
    return f"Run {date}, fruitcli {version}, {processor()}, {os.cpu_count()} cores."
