"""Recordings of raw CDC frames: `.npz` and the MuCa board's ASCII log, read and written.

Units: counts (raw CDC values, not baseline-subtracted), seconds, kPa.

npz keys (loaded with ``allow_pickle=False``): ``frames`` (N, R, C) integer counts,
``t_s`` (N,) host time, optional ``pressure_kpa`` (N, K) with ``chamber_names`` (K,),
optional ``printer_mm`` (N, 3) the printer bench's tip position at each frame (mm,
printer coordinates), optional ``pressure_t_s`` (N,) host time of the pressure reading
each frame carries (NaN before the first reading), optional ``sample`` (N,) int (bench
recordings), ``meta`` a JSON string.

MuCa ASCII log: one frame per line, R*C comma-separated counts in the board's order
(value k is Tx k // C, Rx k % C, so a line reshapes row-major to (R, C)); an empty
field is 0; a line may start with one extra field, the host timestamp in seconds.
Lines with another field count (board log lines such as ``[Muca] Set TEST mode``,
a line cut in the middle) are skipped and counted; ``#`` comment lines are skipped. A line with the
right field count but a non-integer, NaN or negative field is an error in a file
(``strict=True``) and skipped-and-counted on a live port (``strict=False``). A line with
one field too many is a timestamp and counts only when the first field looks like a
host time (a number with a decimal point, non-decreasing down the file); a trailing
comma is dropped; anything else would shift every count onto its neighbour and is
refused. Raw board captures (``.bin``/``.raw``) hold ASCII lines or the firmware's
binary packets (`fruitcli.sensing.frames.muca`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.fsutil import atomic_path
from fruitcli.sensing.frames.board import BOARD_COLS, BOARD_ROWS
from fruitcli.sensing.frames.muca import decode_bytes
from fruitcli.sensing.frames.muca_line import format_line, parse_line
from fruitcli.tables import read_npz_arrays

LOG_SUFFIXES = (".log", ".txt", ".csv", ".muca")
CAPTURE_SUFFIXES = (".bin", ".raw")  # raw bytes from the board, either format


@dataclass
class Recording:
    """Frames with their host times; optional chamber pressures and bench samples."""

    frames: np.ndarray  # (N, R, C) int64 counts
    t_s: np.ndarray  # (N,) float64 s
    pressure_kpa: np.ndarray | None = None  # (N, K) float64 kPa
    chamber_names: tuple[str, ...] = ()
    sample: np.ndarray | None = None  # (N,) int64, -1: not a sample frame
    meta: dict = field(default_factory=dict)
    pressure_t_s: np.ndarray | None = None  # (N,) host time of each frame's pressure
    # reading (s, same clock as t_s; NaN: no reading before that frame, 0 kPa assumed)
    printer_mm: np.ndarray | None = None  # (N, 3) the bench printer's tip at each frame
    skipped_lines: int = 0  # log lines skipped while reading

    def __len__(self) -> int:
        return int(self.frames.shape[0])


BOARD_MAX_COUNTS = 65535
"""Largest count a board reports (16-bit, as `detection.health.SATURATION_COUNTS`)."""


def check_frames(frames: np.ndarray, where: str, first: int = 0) -> np.ndarray:
    """Validate (N, R, C) counts: integers >= 0, at least one frame. Returns int64.
    `first`: index of frames[0] in its recording (a chunk's offset), for the messages."""
    arr = np.asarray(frames)
    if arr.ndim != 3:
        raise FrameError(f"{where}: frames: expected shape (N, rows, cols), got {arr.shape}")
    if arr.shape[0] == 0:
        raise FrameError(f"{where}: empty recording (no frames)")
    if arr.dtype.kind == "f":
        if not np.all(np.isfinite(arr)):
            n = first + int(np.argwhere(~np.isfinite(arr))[0][0])
            raise FrameError(f"{where}: frame {n}: NaN or infinite count")
        if np.any(arr != np.round(arr)):
            n = first + int(np.argwhere(arr != np.round(arr))[0][0])
            raise FrameError(f"{where}: frame {n}: non-integer count")
    elif arr.dtype.kind not in "iu":
        raise FrameError(f"{where}: frames: expected integer counts, got dtype {arr.dtype}")
    if arr.dtype.itemsize > 2 or arr.dtype.kind == "f":  # 16-bit integers are in range
        high = arr > BOARD_MAX_COUNTS
        if np.any(high):
            n, *cell = (int(i) for i in np.argwhere(high)[0])
            value = arr[(n, *cell)].item()
            value = f"{value:.6g}" if isinstance(value, float) else str(value)
            raise FrameError(
                f"{where}: frame {first + n}: count {value} beyond the board's "
                f"range (expected counts 0 to {BOARD_MAX_COUNTS})"
            )
    if arr.dtype.kind == "u":
        return arr.astype(np.int64)  # never negative
    arr = arr.astype(np.int64, copy=False)
    if arr.min() < 0:
        n = first + int(np.argwhere(arr < 0)[0][0])
        raise FrameError(f"{where}: frame {n}: negative count (expected counts >= 0)")
    return arr


def read_npz(path: str | os.PathLike) -> Recording:
    """Read a recording `.npz`; every error names the file and the key."""
    path = Path(path)
    data = read_npz_arrays(path, ".npz recording", FrameError)
    if "frames" not in data:
        raise FrameError(f"{path}: missing key 'frames' (N, rows, cols) counts")
    frames = check_frames(data["frames"], str(path))
    t_s, pressure, names, sample, meta, pressure_t, printer = npz_extras(
        path, data, frames.shape[0]
    )
    return Recording(
        frames, t_s, pressure, names, sample, meta, pressure_t_s=pressure_t, printer_mm=printer
    )


def npz_extras(path: Path, data: Mapping[str, np.ndarray], n: int) -> tuple:
    """Checked t_s, pressure_kpa, chamber_names, sample, meta, pressure_t_s, printer_mm of
    a recording's npz arrays `data` (a mapping) with `n` frames."""
    t_s = data.get("t_s")
    if t_s is None:
        raise FrameError(f"{path}: missing key 't_s' (N,) seconds")
    t_s = np.asarray(t_s, dtype=float)
    if t_s.shape != (n,) or not np.all(np.isfinite(t_s)):
        raise FrameError(f"{path}: t_s: expected {n} finite times, got shape {t_s.shape}")
    meta = {}
    if "meta" in data:
        try:
            meta = json.loads(str(data["meta"]))
        except json.JSONDecodeError as exc:
            raise FrameError(f"{path}: meta: not a JSON string: {exc}") from None
    pressure = None
    names: tuple[str, ...] = ()
    if "pressure_kpa" in data:
        pressure = np.asarray(data["pressure_kpa"], dtype=float)
        if pressure.ndim != 2 or pressure.shape[0] != n or not np.all(np.isfinite(pressure)):
            raise FrameError(
                f"{path}: pressure_kpa: expected ({n}, K) finite kPa, got shape {pressure.shape}"
            )
        names = tuple(str(s) for s in data.get("chamber_names", []))
        if len(names) != pressure.shape[1]:
            names = tuple(f"c{k + 1}" for k in range(pressure.shape[1]))
    pressure_t = None
    if "pressure_t_s" in data:
        pressure_t = np.asarray(data["pressure_t_s"], dtype=float)
        if pressure is None or pressure_t.shape != (n,) or np.any(np.isinf(pressure_t)):
            raise FrameError(
                f"{path}: pressure_t_s: expected ({n},) times (s, NaN before "
                f"the first reading) with pressure_kpa, got {pressure_t.shape}"
            )
    sample = None
    if "sample" in data:
        sample = np.asarray(data["sample"])
        if sample.shape != (n,) or sample.dtype.kind not in "iu":
            raise FrameError(f"{path}: sample: expected ({n},) integers, got {sample.shape}")
        sample = sample.astype(np.int64)
    printer = None
    if "printer_mm" in data:
        printer = np.asarray(data["printer_mm"], dtype=float)
        if printer.shape != (n, 3) or not np.all(np.isfinite(printer)):
            raise FrameError(
                f"{path}: printer_mm: expected ({n}, 3) finite mm, got shape {printer.shape}"
            )
    return t_s, pressure, names, sample, meta, pressure_t, printer


def write_npz(path: str | os.PathLike, rec: Recording) -> None:
    """Write a recording `.npz` atomically."""
    arrays = {
        "frames": check_frames(rec.frames, str(path)),
        "t_s": np.asarray(rec.t_s, dtype=float),
        "meta": np.array(json.dumps(rec.meta)),
    }
    if rec.pressure_kpa is not None:
        arrays["pressure_kpa"] = np.asarray(rec.pressure_kpa, dtype=float)
        arrays["chamber_names"] = np.array(list(rec.chamber_names), dtype=str)
        if rec.pressure_t_s is not None:
            arrays["pressure_t_s"] = np.asarray(rec.pressure_t_s, dtype=float)
    if rec.sample is not None:
        arrays["sample"] = np.asarray(rec.sample, dtype=np.int64)
    if rec.printer_mm is not None:
        arrays["printer_mm"] = np.asarray(rec.printer_mm, dtype=float)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        # numpy's stub: mypy matches **arrays against savez's allow_pickle (bool) too
        np.savez(fh, **arrays)  # type: ignore[arg-type]


def read_muca_log(
    path: str | os.PathLike, rows: int = BOARD_ROWS, cols: int = BOARD_COLS, strict: bool = True
) -> Recording:
    """Read a MuCa ASCII log. Lines with another field count are skipped and counted; in a
    file (`strict`) a bad value, a shifted line or host timestamps that go backwards are
    errors naming the line."""
    path = Path(path)
    if not path.exists():
        raise FrameError(f"{path}: file not found")
    try:
        text = path.read_text(errors="replace")
    except OSError as exc:
        raise FrameError(f"{path}: cannot read: {exc}") from None
    frames, times, skipped = [], [], 0
    last_t, last_t_line = None, 0
    for lineno, line in enumerate(text.splitlines(), start=1):
        if line.startswith("#"):
            continue  # our own header comments
        counts, t, why = parse_line(line, rows * cols)
        if counts is None:
            if strict and why.startswith("value"):
                raise FrameError(f"{path}: line {lineno}: {why[7:]}")
            if strict and why.startswith("shifted"):
                raise FrameError(f"{path}: line {lineno}: {why[9:]}; refusing shifted counts")
            skipped += 1
            continue
        if strict and t is not None:
            if last_t is not None and t < last_t:
                raise FrameError(
                    f"{path}: line {lineno}: host timestamp {t!r} is earlier "
                    f"than line {last_t_line}'s {last_t!r}: the first column is "
                    "not a timestamp column"
                )
            last_t, last_t_line = t, lineno
        frames.append(counts)
        times.append(t)
    if not frames:
        raise FrameError(
            f"{path}: empty recording (no line with {rows * cols} counts; "
            f"{skipped} other lines skipped)"
        )
    stamped = [t is not None for t in times]
    meta = {"source": "muca-log"}
    if all(stamped):
        t_s = np.asarray(times, dtype=float)
    else:
        t_s = np.arange(len(frames), dtype=float)
        meta["t_s"] = "frame index (the log has no host timestamps on every line)"
    arr = np.stack(frames).reshape(-1, rows, cols)
    return Recording(arr, t_s, meta=meta, skipped_lines=skipped)


def read_board_capture(
    path: str | os.PathLike, rows: int = BOARD_ROWS, cols: int = BOARD_COLS, fmt: str = "auto"
) -> Recording:
    """Read raw bytes captured from a board (``cat /dev/ttyACM0 > capture.bin``): ASCII
    lines or SendRawByte packets (`muca_formats`), detected unless `fmt` says. t_s is the
    frame index (a capture has no host times)."""
    path = Path(path)
    if not path.exists():
        raise FrameError(f"{path}: file not found")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise FrameError(f"{path}: cannot read: {exc}") from None
    frames, dec = decode_bytes(data, fmt, rows, cols)
    if not len(frames):
        why = dec.skip_reasons() or "empty file"
        raise FrameError(f"{path}: no {rows} x {cols} frame in the board's {fmt} format ({why})")
    meta = {
        "source": "board capture",
        "format": dec.format,
        "t_s": "frame index (a capture has no host timestamps)",
    }
    return Recording(
        frames, np.arange(len(frames), dtype=float), meta=meta, skipped_lines=int(dec.skipped)
    )


def write_muca_log(path: str | os.PathLike, rec: Recording, timestamps: bool = True) -> None:
    """Write frames as a MuCa ASCII log (with host timestamps unless told not to)."""
    frames = check_frames(rec.frames, str(path))
    lines = [
        format_line(f, t if timestamps else None) for f, t in zip(frames, rec.t_s, strict=True)
    ]
    with atomic_path(path) as tmp:
        Path(tmp).write_text("\n".join(lines) + "\n")


def is_log_path(path: str | os.PathLike) -> bool:
    """True when `path` names a MuCa ASCII log rather than an `.npz`."""
    return Path(path).suffix.lower() in LOG_SUFFIXES


def read_recording(
    path: str | os.PathLike, rows: int = BOARD_ROWS, cols: int = BOARD_COLS, fmt: str = "auto"
) -> Recording:
    """Read an `.npz`, a MuCa ASCII log (.log/.txt/.csv/.muca, host timestamps allowed) or a
    raw board capture (.bin/.raw, or anything else: ASCII or binary per `fmt`)."""
    suffix = Path(path).suffix.lower()
    if suffix == ".npz":
        return read_npz(path)
    if suffix in LOG_SUFFIXES and fmt in ("auto", "ascii"):
        return read_muca_log(path, rows, cols)
    return read_board_capture(path, rows, cols, fmt)
