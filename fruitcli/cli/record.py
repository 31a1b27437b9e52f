"""`fruit record`: record a MuCa board's frames over serial, flushed frame by frame."""

from __future__ import annotations

import click

from fruitcli.cli.options import Progress, fruit_errors


@click.command()
@click.option("--port", required=True, help="Serial port of the board (device path or "
              "pyserial URL).")
@click.option("--out", "out_path", required=True, type=click.Path(dir_okay=False),
              help="Recording: .npz, or a MuCa ASCII log (.log/.txt/.csv) with host "
                   "timestamps.")
@click.option("--frames", "n_frames", type=click.IntRange(min=1), default=None,
              help="Stop after this many frames.")
@click.option("--seconds", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Stop after this many seconds.")
@click.option("--baud", type=click.IntRange(min=1), default=115200, show_default=True,
              help="Baud rate (8N1).")
@click.option("--rows", type=click.IntRange(min=1), default=21, show_default=True,
              help="Frame rows (Tx lines).")
@click.option("--cols", type=click.IntRange(min=1), default=12, show_default=True,
              help="Frame columns (Rx lines).")
@click.option("--format", "fmt", type=click.Choice(["auto", "ascii", "binary"]),
              default="auto", show_default=True,
              help="The board's frame format: stock Muca_Raw ASCII lines or SendRawByte "
                   "binary packets (auto: whichever yields frames first).")
@click.option("--overwrite", is_flag=True,
              help="Replace an existing --out file (once the new recording has frames).")
def record(port, out_path, n_frames, seconds, baud, rows, cols, fmt, overwrite):
    """Record frames from a MuCa board until --frames, --seconds, Ctrl-C or the port closes.

    Every whole frame received is on disk as soon as it arrives; board log lines, cut
    lines and damaged binary packets are skipped and counted. Without --frames or
    --seconds, stop with Ctrl-C.
    """
    from fruitcli.errors import FrameError
    from fruitcli.sensing.recorder import (
        LogSink,
        check_limits,
        check_out_path,
        finalize,
        log_path_for,
        record_stream,
    )
    from fruitcli.sensing.serial_io import FrameReader, open_port

    progress = Progress("[record] ")
    interrupted = False
    with fruit_errors():
        check_limits(n_frames, seconds)
        check_out_path(out_path, overwrite)
        from pathlib import Path

        untouched = (f"{out_path} left as it was" if Path(out_path).exists()
                     else f"nothing written to {out_path}")
        ser = open_port(port, baud)
        reader = FrameReader(ser, rows, cols, name=port, fmt=fmt)
        sink = LogSink(log_path_for(out_path),
                       header=f"fruit record from {port} at {baud} baud: t_s (host, s), "
                              f"{rows}x{cols} counts")
        try:
            res = record_stream(reader, sink, n_frames, seconds, progress)
        except KeyboardInterrupt:
            interrupted = True
            res = {"frames": sink.frames, "skipped": reader.skipped, "cut": reader.cut,
                   "frames_per_s": 0.0, "closed": ""}
        finally:
            sink.close()
            ser.close()
        meta = {"source": "fruit record", "port": port, "baud": baud,
                "format": reader.format}
        frames = finalize(out_path, meta, rows, cols)
        why = reader.skip_reasons()
        unit = "damaged packets" if reader.format == "binary" else "lines"
        skipped = f"{res['skipped']} {unit} skipped" + (f": {why}" if why else "")
        if frames == 0:
            how = ("port closed" if res["closed"] else "interrupted" if interrupted
                   else f"stopped after {seconds:g} s" if seconds else "stopped")
            got = skipped if res["skipped"] or why else "nothing received"
            if interrupted:
                click.echo(f"Interrupted: no frame received from {port}; {untouched} "
                           f"({got})", err=True)
                raise SystemExit(130)
            raise FrameError(f"{port}: no frame received ({how}; {got}); {untouched}")
    summary = (f"{frames} {reader.format} frames ({res['frames_per_s']:.1f} frames/s), "
               f"{skipped}, "
               f"{res['cut']} cut -> {out_path}")
    if res["closed"]:
        raise click.ClickException(f"{port}: port closed after {frames} frames; {out_path} "
                                   f"holds them ({skipped})")
    click.echo(summary, err=True)
    if interrupted:
        click.echo("Interrupted.", err=True)
        raise SystemExit(130)
