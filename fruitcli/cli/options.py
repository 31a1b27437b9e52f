"""Shared click helpers: progress on stderr, FruitError -> one-line ClickException."""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar, cast

import click

from fruitcli.errors import FruitError, one_line

if TYPE_CHECKING:
    from click._termui_impl import ProgressBar

FC = TypeVar("FC", bound=Callable[..., Any])
"""A click command callback, or the command itself: what an option factory's decorator
takes and returns."""


class FiniteFloat(click.FloatRange):
    """A float option that refuses nan and inf (click's FloatRange lets nan through every
    bound), with optional bounds as click.FloatRange."""

    name = "finite float"

    def convert(
        self, value: object, param: click.Parameter | None, ctx: click.Context | None
    ) -> float:
        import math

        # float(value) with click's message; click's stubs give FloatRange two generic bases
        # whose type parameters disagree, so this call does not match its own class's
        number = click.types.FloatParamType.convert(self, value, param, ctx)  # type: ignore[arg-type]
        if not math.isfinite(number):
            self.fail(f"expected a finite number, got {value!r}", param, ctx)
        return super().convert(number, param, ctx)

    def _describe_range(self) -> str:
        """The range for --help; nothing when unbounded (click would print 'x<=None')."""
        return "" if self.min is None and self.max is None else super()._describe_range()


@contextlib.contextmanager
def fruit_errors() -> Iterator[None]:
    """Turn library errors, and operating-system errors such as an unwritable output
    folder, into one-line click errors (exit 1)."""
    try:
        yield
    except FruitError as exc:
        raise click.ClickException(one_line(str(exc))) from None
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


def progressbar(
    iterable: Iterable | None = None, length: int | None = None, label: str = ""
) -> ProgressBar[Any]:
    """A click progress bar on stderr, silent under --quiet."""
    file = open("/dev/null", "w") if quiet() else sys.stderr
    return click.progressbar(
        iterable, length=length, label=label, file=file, show_pos=True, show_eta=True
    )


def reduced_build_bar(total: int) -> ProgressBar[Any]:
    """The progress bar of the reduced model's full solves (`ensure_reduced(bar=...)`)."""
    return progressbar(length=total, label="reduced-model full solves")


divide_by_gain_option = click.option(
    "--divide-by-gain",
    "gains_csv",
    type=click.Path(dir_okay=False),
    default=None,
    metavar="GAINS.csv",
    help="Divide each taxel's activation by its gain from this CSV (id, gain: fruit "
    "calibrate's gains.csv) before detection; the threshold applies to the divided "
    "activations. Default: the scene's [detection].divide_by_gain (off).",
)
"""`fruit locate` and `fruit live`: detection divides by the taxels' calibrated gains."""


# The options several commands share, declared once (as rasterio's `rio/options.py`
# does); each command says what it writes, reads or paces with them.


class OutFolder(click.Path):
    """An output folder: an existing file is left to `claim_out` to refuse in one line
    (click's own check would print its usage too)."""

    def __init__(self, path_type: type | None = None):
        super().__init__(file_okay=False, path_type=path_type)

    def convert(
        self,
        value: str | os.PathLike[str],
        param: click.Parameter | None,
        ctx: click.Context | None,
    ) -> Any:
        if os.path.isfile(value):
            return self.coerce_path_result(value)
        return super().convert(value, param, ctx)


@contextlib.contextmanager
def claim_out(folder: str | Path, option: str = "--out") -> Iterator[None]:
    """Run the block with `folder` as this command's output folder
    (`fruitcli.output_folder.claimed`): a file, an unwritable folder or one holding
    the user's files is refused in one line before anything is written."""
    from fruitcli.output_folder import OutputFolderError, claimed

    ctx = click.get_current_context(silent=True)
    command = f"fruit {ctx.command_path.partition(' ')[2]}".strip() if ctx else "fruit"
    with contextlib.ExitStack() as stack:
        try:
            stack.enter_context(claimed(folder, command, option))
        except OutputFolderError as exc:
            raise click.ClickException(str(exc)) from None
        yield


def out_option(
    written: str,
    *,
    required: bool = True,
    default: str | None = None,
    file: bool = False,
    dest: str = "out_dir",
    path_type: type | None = None,
) -> Callable[[FC], FC]:
    """``--out``: the folder (a file with `file`) the command writes; `written` says what.
    A folder is claimed (`claim_out`) before the command runs; a command whose folder
    is computed when --out is not given claims it itself."""
    kind = click.Path(dir_okay=False, path_type=path_type) if file else OutFolder(path_type)
    option = click.option(
        "--out",
        dest,
        required=required,
        default=default,
        type=kind,
        show_default=default is not None,
        help=written,
    )
    if file:
        return option

    def decorate(command: FC) -> FC:
        @functools.wraps(command)
        def claiming(*args, **kwargs):
            if kwargs.get(dest) is None:
                return command(*args, **kwargs)
            with claim_out(kwargs[dest]):
                return command(*args, **kwargs)

        # functools.wraps keeps the command's name and signature: still an FC to click
        return cast(FC, option(claiming))

    return decorate


def taxels_option(*, required: bool = False, path_type: type | None = None) -> Callable[[FC], FC]:
    """``--taxels``: the taxel CSV; by default the scene's own."""
    where = (
        "."
        if required
        else "; default: the scene's own (its stages run into out/<scene name> when needed)."
    )
    return click.option(
        "--taxels",
        "taxels_csv",
        required=required,
        default=None,
        type=click.Path(dir_okay=False, path_type=path_type),
        help=f"Taxel CSV: id,i,j,x_mm,y_mm,z_mm (mm, rest positions){where}",
    )


def states_option(follows: str) -> Callable[[FC], FC]:
    """``--states``: `fruit simulate`'s states.npz; `follows` says what the taxels do."""
    return click.option(
        "--states",
        "states_npz",
        type=click.Path(dir_okay=False),
        default=None,
        help=f"states.npz from `fruit simulate`: {follows}",
    )


def format_option(*, default: str | None, auto: bool = True, what: str = "") -> Callable[[FC], FC]:
    """``--format``: the board's frame format (stock Muca_Raw ASCII lines or SendRawByte
    binary packets); `auto` adds auto-detection; `what` says what it applies to."""
    from fruitcli.sensing.frames.formats import BOARD_FORMATS

    choices = (["auto"] if auto else []) + list(BOARD_FORMATS)
    if default is None:
        tail = " Default: the scene's [board].format."
    elif default == "auto":
        tail = " auto: whichever yields frames first."
    else:
        tail = ""
    return click.option(
        "--format",
        "fmt",
        type=click.Choice(choices),
        default=default,
        show_default=default is not None,
        help=f"{what}The board's frame format: stock Muca_Raw ASCII lines or "
        f"SendRawByte binary packets.{tail}",
    )


def baud_option(*, name: str = "--baud", pace: bool = False, what: str = "") -> Callable[[FC], FC]:
    """``--baud``: a serial line's baud rate (8N1); with `pace` an emulator paces its bytes
    at it and 0 means unpaced."""
    help_text = (
        (f"{what}Pace the bytes like a serial line at this baud, 8N1 (10 bits a byte; 0: unpaced).")
        if pace
        else f"{what}Baud rate (8N1)."
    )
    return click.option(
        name,
        type=click.IntRange(min=0 if pace else 1),
        default=115200,
        show_default=True,
        help=help_text,
    )


def jobs_option(what: str = "Worker processes") -> Callable[[FC], FC]:
    """``--jobs``: local worker processes (default: all cores)."""
    return click.option(
        "--jobs", type=click.IntRange(min=1), default=None, help=f"{what}. [default: all cores]"
    )


def scheduler_option(what: str) -> Callable[[FC], FC]:
    """``--scheduler ADDRESS``: a Dask distributed scheduler to run `what` on."""
    return click.option(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help=f"Run {what} on the workers of this Dask distributed scheduler "
        "(tcp://host:8786), e.g. one started by dask-jobqueue on SLURM "
        "or PBS; --out must be on a file system they share. Needs pip "
        "install 'fruit-touch[cluster]'.",
    )


# The detection options `fruit locate` and `fruit live` share; each falls back on the
# scene's [detection] (or [skin]) when not given.
baseline_frames_option = click.option(
    "--baseline-frames",
    type=click.IntRange(min=1),
    default=None,
    help="Frames averaged into the baseline C0 (default: the scene's "
    "[detection].baseline_frames, 10).",
)
threshold_option = click.option(
    "--threshold",
    type=FiniteFloat(min=0, min_open=True),
    default=None,
    help="Touch threshold on v = C - C0, counts (default: the scene's "
    "[detection].threshold_counts, 20).",
)
skin_table_option = click.option(
    "--skin",
    "skin_toml",
    type=click.Path(dir_okay=False),
    default=None,
    help="A [skin] table (e.g. `fruit calibrate`'s skin.toml) whose gap law gives the "
    "touches' heights and strengths (default: the scene's [skin]).",
)
hovers_option = click.option(
    "--hovers",
    is_flag=True,
    default=None,
    help="Report hovers (below the touch threshold) as touches of kind hover (default: the "
    "scene's [detection].hovers).",
)
