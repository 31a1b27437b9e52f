"""Recording a live board: frames appended to a MuCa log, flushed frame by frame.

Units: counts, s. Frames are recorded into ``<out>.partial.log`` and moved (a log) or
converted (an `.npz`) onto `out` when recording ends with at least one frame, so an
existing `out` is replaced only by a recording that has frames (and only with
``--overwrite``). A Ctrl-C or an unplugged cable ends the recording normally; after a
hard crash the partial log remains, a valid recording itself (a line cut by the end is
not a frame and is not written), and a new recording refuses to start over it.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.sensing.frames.recording import (
    LOG_SUFFIXES,
    Recording,
    format_line,
    is_log_path,
    read_muca_log,
    write_npz,
)
from fruitcli.sensing.live.serial_ports import FrameReader, PortClosed

if TYPE_CHECKING:
    from fruitcli.sensing.live.serial_ports import PressureState

PROGRESS_EVERY_S = 1.0  # frames/s progress reports this often


class LogSink:
    """A MuCa log with host timestamps (s), one flushed line per frame; with `pressure`
    (a PressureState) also a CSV line per frame, ``t_s,kPa...``: the latest pressures
    received before the frame and the time of that reading (on the clock that started at
    monotonic `t0`, like the frames' t_s; ``nan`` before the first reading)."""

    def __init__(
        self,
        path: str | os.PathLike,
        header: str = "",
        pressure: PressureState | None = None,
        t0: float = 0.0,
    ):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.fh = open(self.path, "x")
        if header:
            self.fh.write(f"# {header}\n")
            self.fh.flush()
        self.frames = 0
        self.pressure, self.t0 = pressure, t0
        self.pfh = None
        if pressure is not None:
            self.pfh = open(pressure_path_for(self.path), "x")

    def write(self, counts: np.ndarray, t_s: float) -> None:
        if self.pfh is not None and self.pressure is not None:  # the pressures before the
            # frame, written just after it
            kpa, t = self.pressure.latest
            self.fh.write(format_line(counts, t_s) + "\n")
            self.pfh.write(
                ",".join([repr(float(t - self.t0))] + [repr(float(v)) for v in kpa]) + "\n"
            )
            self.fh.flush()
            self.pfh.flush()
        else:
            self.fh.write(format_line(counts, t_s) + "\n")
            self.fh.flush()
        self.frames += 1

    def close(self) -> None:
        self.fh.close()
        if self.pfh is not None:
            self.pfh.close()


def pressure_path_for(log: str | os.PathLike) -> Path:
    """The pressure CSV written next to a partial log."""
    log = Path(log)
    return log.with_name(log.name.removesuffix(".log") + ".pressure.csv")


def read_pressure_csv(path: Path, n_chambers: int) -> tuple[np.ndarray, np.ndarray]:
    """(t_s (M,), kPa (M, K)) of a pressure CSV; a line cut by a crash ends it."""
    times, kpa = [], []
    for line in path.read_text().splitlines():
        parts = line.split(",")
        if len(parts) != n_chambers + 1:
            break
        try:
            vals = [float(v) for v in parts]
        except ValueError:
            break
        times.append(vals[0])
        kpa.append(vals[1:])
    return np.asarray(times, float), np.asarray(kpa, float).reshape(-1, n_chambers)


def log_path_for(out: str | os.PathLike) -> Path:
    """Where frames are flushed while recording to `out`."""
    out = Path(out)
    return out.with_name(out.name + ".partial.log")


def finalize(
    out: str | os.PathLike, meta: dict, rows: int, cols: int, chambers: tuple[str, ...] = ()
) -> int:
    """Move (a log) or convert (an `.npz`, with the pressures of `chambers` when given)
    the partial log onto `out`. -> frames.

    Without a frame, the partial files are removed and `out` is left as it was."""
    out = Path(out)
    log = log_path_for(out)
    plog = pressure_path_for(log)
    if not _has_frames(log, rows * cols):
        log.unlink(missing_ok=True)
        plog.unlink(missing_ok=True)
        return 0
    rec = read_muca_log(log, rows, cols, strict=False)
    if is_log_path(out):
        os.replace(log, out)
        return len(rec)
    rec.meta.update(meta)
    if chambers:
        t, kpa = read_pressure_csv(plog, len(chambers))
        n = min(len(rec), len(t))  # a crash between the two lines: drop the odd frame
        rec = Recording(
            rec.frames[:n],
            rec.t_s[:n],
            np.nan_to_num(kpa[:n], nan=0.0),
            tuple(chambers),
            meta=rec.meta,
            pressure_t_s=t[:n],
        )
    write_npz(out, rec)
    log.unlink()
    plog.unlink(missing_ok=True)
    return len(rec)


def _has_frames(path: Path, n_cells: int) -> bool:
    with open(path) as fh:
        return any(line.count(",") >= n_cells - 1 for line in fh)


def record_stream(
    reader: FrameReader,
    sink: LogSink,
    n_frames: int | None = None,
    seconds: float | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict:
    """Copy frames from `reader` to `sink` until `n_frames`, `seconds` or the port closes.

    Returns {frames, skipped, cut, seconds, frames_per_s, closed (message or "")}."""
    t0 = time.monotonic()
    last = t0
    closed = ""
    try:
        while True:
            now = time.monotonic()
            if seconds is not None and now - t0 >= seconds:
                break
            if n_frames is not None and sink.frames >= n_frames:
                break
            for counts, t_s, _ in reader.poll():
                sink.write(counts, t_s)
                if n_frames is not None and sink.frames >= n_frames:
                    break
            if progress and now - last >= PROGRESS_EVERY_S:
                why = reader.skip_reasons() if not sink.frames else ""
                progress(
                    f"{sink.frames} frames, {sink.frames / (now - t0):.1f} frames/s"
                    + (f", {reader.skipped} lines skipped: {why}" if why else "")
                )
                last = now
    except PortClosed as exc:
        closed = str(exc)
        for counts, t_s, _ in reader.finish():  # binary: the last packet, when whole
            if n_frames is None or sink.frames < n_frames:
                sink.write(counts, t_s)
    dt = time.monotonic() - t0
    return {
        "frames": sink.frames,
        "skipped": reader.skipped,
        "cut": reader.cut,
        "seconds": dt,
        "frames_per_s": sink.frames / dt if dt > 0 else 0.0,
        "closed": closed,
    }


def check_limits(n_frames: int | None, seconds: float | None) -> None:
    if n_frames is not None and seconds is not None:
        raise FrameError("give --frames or --seconds, not both")


def check_out_path(
    out: str | os.PathLike, overwrite: bool = False, pressures: bool = False
) -> None:
    """`out` must be an `.npz` or a MuCa log by its suffix (an `.npz` with `pressures`),
    must not exist unless `overwrite`, and no partial log of an unfinished recording may
    be in the way."""
    suffix = Path(out).suffix.lower()
    if suffix != ".npz" and not is_log_path(out):
        raise FrameError(
            f"--out {out}: expected a .npz or a MuCa log "
            f"({', '.join(LOG_SUFFIXES)}), got {suffix or 'no suffix'!r}"
        )
    if pressures and suffix != ".npz":
        raise FrameError(
            f"--out {out}: chamber pressures are recorded in an .npz only "
            "(a MuCa log has no place for them)"
        )
    if Path(out).is_dir():
        raise FrameError(f"--out {out}: is a folder, expected a file")
    if not Path(out).absolute().parent.is_dir():
        raise FrameError(f"--out {out}: folder {Path(out).parent} does not exist; create it first")
    if Path(out).exists() and not overwrite:
        raise FrameError(
            f"--out {out}: exists; give --overwrite to replace it (it is "
            "replaced only once the new recording has frames)"
        )
    partial = log_path_for(out)
    if not partial.exists() and pressure_path_for(partial).exists():
        partial = pressure_path_for(partial)
    if partial.exists():
        raise FrameError(
            f"{partial}: left by a recording that did not finish (it holds "
            "its frames, a MuCa log); move or remove it first"
        )
