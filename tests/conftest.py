"""Shared fixtures: a CLI runner on the `fruit` group, paths to the bundled data."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")
# tests stop `fruit live` subprocesses with SIGINT, as a terminal does; a shell's background
# job starts with SIGINT ignored, which its children would inherit (and never stop)
signal.signal(signal.SIGINT, signal.default_int_handler)

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "data" / "paper"


@pytest.fixture
def runner():
    from click.testing import CliRunner

    return CliRunner()


@pytest.fixture
def fruit(runner):
    """Invoke `fruit ARGS...`; returns click's Result."""
    from fruitcli.cli.main import cli

    def call(*args):
        return runner.invoke(cli, [str(a) for a in args], catch_exceptions=False)

    return call
