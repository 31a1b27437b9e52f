"""`fruit record`: record a MuCa board's frames over serial, flushed frame by frame."""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import click

from fruitcli.cli.options import (
    FiniteFloat,
    Progress,
    baud_option,
    format_option,
    fruit_errors,
    out_option,
)

if TYPE_CHECKING:
    from fruitcli.sensing.live.serial_ports import PressureState


@click.command()
@click.option(
    "--port", required=True, help="Serial port of the board (device path or pyserial URL)."
)
@out_option(
    "Recording: .npz, or a MuCa ASCII log (.log/.txt/.csv) with host timestamps.",
    file=True,
    dest="out_path",
)
@click.option(
    "--frames",
    "n_frames",
    type=click.IntRange(min=1),
    default=None,
    help="Stop after this many frames.",
)
@click.option(
    "--seconds",
    type=FiniteFloat(min=0, min_open=True),
    default=None,
    help="Stop after this many seconds.",
)
@baud_option()
@click.option(
    "--rows",
    type=click.IntRange(min=1),
    default=21,
    show_default=True,
    help="Frame rows (Tx lines).",
)
@click.option(
    "--cols",
    type=click.IntRange(min=1),
    default=12,
    show_default=True,
    help="Frame columns (Rx lines).",
)
@format_option(default="auto")
@click.option(
    "--pressure-port",
    default=None,
    help="Serial source of chamber pressures, the `fruit live` line protocol "
    "'P c1=2.5 c2=0.0' (kPa): each frame gets the latest pressures received "
    "before it (pressure_kpa) and the time of that reading (pressure_t_s). "
    "Needs --chambers and an .npz --out.",
)
@click.option(
    "--chambers",
    default=None,
    help="Chamber names of --pressure-port, comma-separated (e.g. c1,c2,c3): the "
    "columns of pressure_kpa; lines naming others are skipped and counted.",
)
@click.option(
    "--overwrite",
    is_flag=True,
    help="Replace an existing --out file (once the new recording has frames).",
)
def record(
    port, out_path, n_frames, seconds, baud, rows, cols, fmt, pressure_port, chambers, overwrite
) -> None:
    """Record frames from a MuCa board until --frames, --seconds, Ctrl-C or the port closes.

    Every whole frame received is on disk as soon as it arrives; board log lines, cut
    lines and damaged binary packets are skipped and counted. Without --frames or
    --seconds, stop with Ctrl-C.
    """
    from fruitcli.errors import FrameError
    from fruitcli.sensing.live.loop import pressure_thread
    from fruitcli.sensing.live.recorder import (
        LogSink,
        check_limits,
        check_out_path,
        finalize,
        log_path_for,
        record_stream,
    )
    from fruitcli.sensing.live.serial_ports import FrameReader, PressureState, open_port

    progress = Progress("[record] ")
    interrupted = False
    with fruit_errors():
        check_limits(n_frames, seconds)
        names = _chamber_names(chambers, pressure_port)
        check_out_path(out_path, overwrite, pressures=bool(pressure_port))
        from pathlib import Path

        untouched = (
            f"{out_path} left as it was"
            if Path(out_path).exists()
            else f"nothing written to {out_path}"
        )
        ser = open_port(port, baud)
        pser = p_thread = pressure = None
        stop = threading.Event()
        if pressure_port:
            try:
                pser = open_port(pressure_port, baud)
            except FrameError:
                ser.close()
                raise
            pressure = PressureState(names)
        reader = FrameReader(ser, rows, cols, name=port, fmt=fmt)
        if pressure is not None:
            p_thread = pressure_thread(pser, pressure, stop, pressure_port)
        sink = LogSink(
            log_path_for(out_path),
            header=f"fruit record from {port} at {baud} baud: t_s (host, s), {rows}x{cols} counts",
            pressure=pressure,
            t0=reader.t0,
        )
        started = time.monotonic()
        try:
            res = record_stream(reader, sink, n_frames, seconds, progress)
        except KeyboardInterrupt:
            interrupted = True
            took = time.monotonic() - started
            res = {
                "frames": sink.frames,
                "skipped": reader.skipped,
                "cut": reader.cut,
                "frames_per_s": sink.frames / took if took > 0 else 0.0,
                "closed": "",
            }
        finally:
            sink.close()
            ser.close()
            stop.set()
            if p_thread is not None:
                p_thread.join(1.0)
            if pser is not None:
                pser.close()
        meta = {"source": "fruit record", "port": port, "baud": baud, "format": reader.format}
        if pressure is not None:
            meta.update(
                pressure_port=pressure_port,
                pressure_lines=pressure.received,
                pressure_lines_skipped=pressure.skipped,
            )
        frames = finalize(out_path, meta, rows, cols, names)
        why = reader.skip_reasons()
        unit = "damaged packets" if reader.format == "binary" else "lines"
        skipped = f"{res['skipped']} {unit} skipped" + (f": {why}" if why else "")
        if frames == 0:
            _no_frames(port, res, interrupted, seconds, skipped, why, untouched)
    summary = _summary(frames, reader.format, res, skipped, out_path, pressure, names)
    if res["closed"]:
        raise click.ClickException(
            f"{port}: port closed after {frames} frames; {out_path} holds them ({skipped})"
        )
    click.echo(summary, err=True)
    if interrupted:
        click.echo("Interrupted.", err=True)
        raise SystemExit(130)


def _chamber_names(chambers: str | None, pressure_port: str | None) -> tuple[str, ...]:
    """The names of --chambers (comma-separated), checked against --pressure-port."""
    from fruitcli.errors import FrameError

    names = tuple(c.strip() for c in chambers.split(",")) if chambers else ()
    if pressure_port and not names:
        raise FrameError(
            f"--pressure-port {pressure_port}: give --chambers, the names "
            "of the pressures' columns (e.g. --chambers c1,c2,c3)"
        )
    if names and not pressure_port:
        raise FrameError("--chambers: needs --pressure-port, the source of the pressures")
    if any(not c for c in names) or len(set(names)) != len(names):
        raise FrameError(f"--chambers {chambers}: expected distinct non-empty names")
    return names


def _no_frames(
    port: str,
    res: dict,
    interrupted: bool,
    seconds: float | None,
    skipped: str,
    why: str,
    untouched: str,
) -> None:
    """Stop a recording that got no frame: exit 130 when interrupted, else a FrameError
    saying how it stopped and what it skipped."""
    from fruitcli.errors import FrameError

    how = (
        "port closed"
        if res["closed"]
        else "interrupted"
        if interrupted
        else f"stopped after {seconds:g} s"
        if seconds
        else "stopped"
    )
    got = skipped if res["skipped"] or why else "nothing received"
    if interrupted:
        click.echo(f"Interrupted: no frame received from {port}; {untouched} ({got})", err=True)
        raise SystemExit(130)
    raise FrameError(f"{port}: no frame received ({how}; {got}); {untouched}")


def _summary(
    frames: int,
    fmt: str | None,
    res: dict,
    skipped: str,
    out_path: str | Path,
    pressure: PressureState | None,
    names: Sequence[str],
) -> str:
    """The line a recording ends with: frames, rate, lines skipped and cut, pressures."""
    summary = (
        f"{frames} {fmt} frames ({res['frames_per_s']:.1f} frames/s), "
        f"{skipped}, "
        f"{res['cut']} cut -> {out_path}"
    )
    if pressure is not None:
        summary += (
            f"; pressure lines: {pressure.received} taken, {pressure.skipped} skipped "
            f"(not 'P name=kPa ...' with chambers {', '.join(names)})"
            + ("; the pressure port closed during the recording" if pressure.closed else "")
        )
    return summary
