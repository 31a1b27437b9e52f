"""The `fruit` command group. Subcommands live one per module in `fruitcli.cli` and
are imported only when used, so `fruit --help` stays fast."""

from __future__ import annotations

import atexit
import contextlib
import difflib
import importlib
import logging
import os
import signal
import sys
import warnings
import weakref
from typing import TYPE_CHECKING

import click

from fruitcli import DISTRIBUTION, compile_notice

if TYPE_CHECKING:
    from types import FrameType
    from typing import TextIO

# name -> (module, attribute, one-line help shown by `fruit --help`)
COMMANDS: dict[str, tuple[str, str, str]] = {
    "run": ("fruitcli.cli.run", "run", "Run every stage a scene needs (planner, reuse)."),
    "make-artist": (
        "fruitcli.cli.make_artist",
        "make_artist",
        "Write the default artist mesh (the organic 'Fruit').",
    ),
    "make-tracks": (
        "fruitcli.cli.make_tracks",
        "make_tracks",
        "Reduce an artist mesh, carve yarn tracks, export taxels.",
    ),
    "make-mold": (
        "fruitcli.cli.make_mold",
        "make_mold",
        "Printable molds for a scene's cast pieces (shells, plates, cores).",
    ),
    "tetra": ("fruitcli.cli.tetra", "tetra", "Tetrahedralize a scene's body with its chambers."),
    "simulate": (
        "fruitcli.cli.simulate",
        "simulate",
        "Quasi-static FEM of a scene's states ([fem].element, [material].model).",
    ),
    "limits": (
        "fruitcli.cli.limits",
        "limits",
        "Each chamber's limit pressure, followed past it by volume control.",
    ),
    "bench": ("fruitcli.cli.bench", "bench", "Virtual 3D-printer bench: frames with ground truth."),
    "skin": ("fruitcli.cli.skin", "skin", "Electrostatics of a yarn crossing: C0, dC, C_delta."),
    "locate": ("fruitcli.cli.locate", "locate", "Detect touches in frames and map them to 3D."),
    "record": ("fruitcli.cli.record", "record", "Record frames from a MuCa board over serial."),
    "live": ("fruitcli.cli.live", "live", "Localize touches live from a MuCa board."),
    "emulate-board": (
        "fruitcli.cli.emulate_board",
        "emulate_board",
        "Play frames on a pseudo-terminal like a MuCa board.",
    ),
    "emulate-printer": (
        "fruitcli.cli.emulate_printer",
        "emulate_printer",
        "A Marlin-like printer and a skin-touching board on two ptys.",
    ),
    "calibrate": (
        "fruitcli.cli.calibrate",
        "calibrate",
        "Fit the skin's forward model to a bench recording.",
    ),
    "evaluate": (
        "fruitcli.cli.evaluate",
        "evaluate",
        "Error tables and plots against ground truth.",
    ),
    "study": ("fruitcli.cli.study", "study", "Error-against-run-time and stability studies."),
    "sweep": (
        "fruitcli.cli.sweep",
        "sweep",
        "Run a scene for many values of its keys (local or on a Dask cluster).",
    ),
    "demo": ("fruitcli.cli.demo", "demo", "Run the default experiments and write out/report.md."),
    "scenes": (
        "fruitcli.cli.scenes",
        "scenes",
        "List the bundled example scenes; copy one to start your own.",
    ),
}


class LazyGroup(click.Group):
    """A click group that imports a subcommand's module on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in COMMANDS:
            return None
        module, attr, _ = COMMANDS[name]
        return accept_late_options(getattr(importlib.import_module(module), attr))

    def resolve_command(self, ctx: click.Context, args: list[str]):  # noqa: ANN201
        """click's, with the closest command names suggested for an unknown one."""
        name = args[0] if args else ""
        if name and not name.startswith("-") and name not in COMMANDS:
            close = difflib.get_close_matches(name, list(COMMANDS), n=3, cutoff=0.7)
            if close and not ctx.resilient_parsing:
                hint = " or ".join(repr(c) for c in close)
                ctx.fail(f"No such command {name!r}. Did you mean {hint}?")
        return super().resolve_command(ctx, args)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(name, short) for name, (_, _, short) in COMMANDS.items()]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


def use_solver_threads(threads: int) -> None:
    """Ask MKL PARDISO for `threads` threads (`--solver-threads`), at most the cores (with
    a warning), before anything loads MKL (`pardiso.use_threads`); 1 changes nothing."""
    if threads <= 1:
        return
    from fruitcli.fem.solver import pardiso

    cores = os.cpu_count() or 1
    if threads > cores:
        logging.getLogger(__name__).warning(
            f"--solver-threads {threads}: this machine has {cores} cores; {cores}"
        )
    pardiso.use_threads(min(threads, cores))


def log_level(verbose: int, quiet: bool) -> int:
    """The logging level of -v (counted) and -q."""
    return logging.ERROR if quiet else max(logging.WARNING - 10 * verbose, logging.DEBUG)


def _late_option(ctx: click.Context, param: click.Parameter, value: object) -> None:
    """-v, -q or --solver-threads given after the subcommand: the same as given before
    it."""
    if not value:
        return
    if param.name == "solver_threads":
        use_solver_threads(int(value))  # type: ignore[call-overload]
        return
    obj = ctx.find_root().ensure_object(dict)
    if param.name == "verbose":
        obj["verbose"] = obj.get("verbose", 0) + value
    else:
        obj["quiet"] = True
    logging.getLogger().setLevel(log_level(obj.get("verbose", 0), obj.get("quiet", False)))


_LATE_OPTIONS: weakref.WeakSet[click.Command] = weakref.WeakSet()
"""The commands `accept_late_options` has given -v, -q and --solver-threads."""


def accept_late_options(cmd: click.Command) -> click.Command:
    """`cmd` (and the commands of a group, at every level) also taking the group's -v, -q
    and --solver-threads after its name (hidden from its --help: they are the group's
    options)."""
    if cmd in _LATE_OPTIONS:
        return cmd
    names = {n for p in cmd.params for n in getattr(p, "opts", [])}
    for flags, count in ((("-v", "--verbose"), True), (("-q", "--quiet"), False)):
        if names.isdisjoint(flags):
            cmd.params.append(
                click.Option(
                    flags,
                    is_flag=not count,
                    count=count,
                    hidden=True,
                    expose_value=False,
                    callback=_late_option,
                )
            )
    if "--solver-threads" not in names:
        cmd.params.append(
            click.Option(
                ("--solver-threads",),
                type=click.IntRange(min=1),
                hidden=True,
                expose_value=False,
                callback=_late_option,
            )
        )
    _LATE_OPTIONS.add(cmd)
    for sub in getattr(cmd, "commands", {}).values():
        accept_late_options(sub)
    return cmd


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.option("-v", "--verbose", count=True, help="More log output; -vv shows tracebacks.")
@click.option("-q", "--quiet", is_flag=True, help="No progress output on stderr.")
@click.option(
    "--solver-threads",
    type=click.IntRange(min=1),
    default=1,
    show_default=True,
    metavar="N",
    help="Threads of MKL PARDISO's factorizations and solves in the FEM (at most the "
    "cores). 1: every run's results the same to the last bit; more: faster "
    "factorizations on an idle machine, results varying between runs within the solver's "
    "tolerances.",
)
@click.version_option(package_name=DISTRIBUTION, prog_name="fruit")
@click.pass_context
def cli(ctx, verbose, quiet, solver_threads) -> None:
    """fruit: model-based capacitive touch sensing on soft robots.

    From an artist's mesh to a fabricated, calibrated, evaluated touch skin.
    Units everywhere: mm, kPa, degrees, seconds, CDC counts.
    """
    ctx.ensure_object(dict)
    ctx.obj["verbose"] = verbose
    ctx.obj["quiet"] = quiet
    compile_notice.silence(quiet)
    logging.basicConfig(level=log_level(verbose, quiet), format="%(message)s", stream=sys.stderr)
    use_solver_threads(solver_threads)


def main(argv: list[str] | None = None) -> None:
    """Console entry point: FruitErrors become one line on stderr and exit code 1; Ctrl-C,
    up to the process's last instant, "Interrupted." and exit code 130. From the console
    (`argv` None) an interrupted command then ends the process through `_exit_now`;
    called with `argv`, it raises SystemExit."""
    try:
        try:
            return _main(argv)
        except KeyboardInterrupt:  # while an error or the result was being reported
            click.echo("Interrupted.", err=True)
            sys.exit(130)
    except SystemExit as exc:
        if argv is None and exc.code == 130:
            _exit_now(130)
        raise
    finally:
        # the console script (the interpreter's shutdown follows), unless Ctrl-C is ignored
        # (a background job)
        if argv is None and signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
            signal.signal(signal.SIGINT, _interrupted_at_exit)
            atexit.register(_hold_interrupts)  # runs first of the exit functions


def _exit_now(code: int) -> None:
    """End the process with `code` the way the interpreter's exit starts (non-daemon
    threads joined, exit functions run: worker pools and multiprocessing's semaphores
    are cleaned up there, stdout and stderr flushed), then skip the interpreter's
    finalization. A `fruit run` interrupted as its evaluate stage began was now and then
    aborted during finalization ("Fatal Python error: PyThreadState_Get: ... the GIL is
    released", exit -6 instead of 130). `threading._shutdown` and
    `atexit._run_exitfuncs` are the two steps the interpreter takes first at its exit;
    Python has no public call for them. A further Ctrl-C meanwhile is ignored."""
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    with contextlib.suppress(Exception):
        threading._shutdown()  # type: ignore[attr-defined]
    with contextlib.suppress(Exception):
        atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(code)


def _hold_interrupts() -> None:
    """At the interpreter's exit, ignore Ctrl-C in the whole process: late in shutdown
    Python gives a handled SIGINT its default action again, and a Ctrl-C delivered there
    (to any thread: a mask holds only the thread that set it) ended the process by the
    signal, with no line. Ignored, it stays ignored: the command, already done, exits
    with its own code."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _interrupted_at_exit(signum: int, frame: FrameType | None) -> None:
    """Ctrl-C once the command is over (threads joined, files closed at exit): what was
    printed is flushed, then "Interrupted." and exit code 130 at once."""
    with contextlib.suppress(Exception):
        sys.stdout.flush()
    with contextlib.suppress(Exception):
        sys.stderr.write("Interrupted.\n")
        sys.stderr.flush()
    os._exit(130)


def show_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """A library's warning as one line on stderr, "warning: Category: text" (its file,
    line and source left out; -vv keeps Python's own form)."""
    from fruitcli.errors import one_line

    click.echo(f"warning: {one_line(f'{category.__name__}: {message}')}", err=True)


def _main(argv: list[str] | None) -> None:
    from fruitcli.errors import FruitError, one_line

    if "-vv" not in (argv or sys.argv):
        warnings.showwarning = show_warning
    compile_notice.install(lambda line: click.echo(line, err=True))
    try:
        return cli.main(args=argv, standalone_mode=False)
    except click.exceptions.Abort as exc:  # click turns Ctrl-C into Abort; EOF at a prompt too
        click.echo("Interrupted." if _interrupted(exc) else "Aborted.", err=True)
        sys.exit(130)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except FruitError as exc:
        if "-vv" in (argv or sys.argv):
            raise
        click.echo(f"Error: {one_line(str(exc))}", err=True)
        sys.exit(1)
    except OSError as exc:  # an unwritable output folder, a full disk, ...
        if "-vv" in (argv or sys.argv):
            raise
        from fruitcli.cli.options import os_error_line

        click.echo(f"Error: {os_error_line(exc)}", err=True)
        sys.exit(1)
    except KeyboardInterrupt:
        click.echo("Interrupted.", err=True)
        sys.exit(130)
    except Exception as exc:
        if not _interrupted(exc) or "-vv" in (argv or sys.argv):
            raise
        click.echo("Interrupted.", err=True)
        sys.exit(130)


def _interrupted(exc: BaseException) -> bool:
    """True when Ctrl-C caused `exc`: a compiled kernel (numba, a C extension) that was
    running when SIGINT came raises SystemError "returned a result with an exception set"
    with the KeyboardInterrupt as its cause or context."""
    seen = set()
    link: BaseException | None = exc
    while link is not None and id(link) not in seen:
        if isinstance(link, KeyboardInterrupt):
            return True
        seen.add(id(link))
        link = link.__cause__ or link.__context__
    return False
