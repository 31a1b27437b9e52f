"""Shared click helpers: progress on stderr, FruitError -> one-line ClickException."""

from __future__ import annotations

import contextlib
import sys
import time

import click

from fruitcli.errors import FruitError


@contextlib.contextmanager
def fruit_errors():
    """Turn library errors, and operating-system errors such as an unwritable output
    folder, into one-line click errors (exit 1)."""
    try:
        yield
    except FruitError as exc:
        raise click.ClickException(str(exc)) from None
    except OSError as exc:
        raise click.ClickException(os_error_line(exc)) from None


def os_error_line(exc: OSError) -> str:
    """'path: reason' for an operating-system error (e.g. a read-only output folder)."""
    where = exc.filename or ""
    if exc.filename2:
        where = f"{exc.filename} -> {exc.filename2}"
    reason = exc.strerror or str(exc)
    return f"{where}: {reason}" if where else reason


def quiet(ctx: click.Context | None = None) -> bool:
    ctx = ctx or click.get_current_context(silent=True)
    root = ctx.find_root() if ctx else None
    return bool(root and root.obj and root.obj.get("quiet"))


class Progress:
    """Step progress lines on stderr: `progress("reduce", 0.42)` prints `[reduce] 0.42 s`."""

    def __init__(self, prefix: str = ""):
        self.prefix = prefix
        self.silent = quiet()
        self.t0 = time.perf_counter()

    def __call__(self, message: str) -> None:
        if not self.silent:
            dt = time.perf_counter() - self.t0
            click.echo(f"{self.prefix}[{dt:7.2f} s] {message}", err=True)
            sys.stderr.flush()


def progressbar(iterable=None, length=None, label=""):
    """A click progress bar on stderr, silent under --quiet."""
    file = open("/dev/null", "w") if quiet() else sys.stderr  # noqa: SIM115
    return click.progressbar(iterable, length=length, label=label, file=file,
                             show_pos=True, show_eta=True)


divide_by_gain_option = click.option(
    "--divide-by-gain", "gains_csv", type=click.Path(dir_okay=False), default=None,
    metavar="GAINS.csv",
    help="Divide each taxel's activation by its gain from this CSV (id, gain: fruit "
         "calibrate's gains.csv) before detection; the threshold applies to the divided "
         "activations. Default: the scene's [detection].divide_by_gain (off).")
"""`fruit locate` and `fruit live`: detection divides by the taxels' calibrated gains."""
