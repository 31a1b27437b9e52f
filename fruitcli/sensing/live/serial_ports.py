"""Serial input: MuCa frames and chamber-pressure lines from pyserial ports.

Units: counts, kPa, s (host monotonic time since the port was opened).

A port that does not exist, is busy, or vanishes (unplugged cable, closed pseudo-
terminal) raises `FrameError` with one line naming the port. Lines that are not frames
(board log lines, cut lines, bad values, shifted lines) and bytes outside binary packets
are skipped and counted, never fatal.

Pressure line protocol (``fruit live --pressure-port``): one ASCII line per reading,
``P <chamber>=<kPa> [<chamber>=<kPa> ...]`` terminated by ``\\n`` (``\\r\\n`` accepted),
e.g. ``P c1=2.5 c2=0.0``. Chambers not named keep their last value (0 kPa at start);
other lines are skipped and counted.
"""

from __future__ import annotations

import errno
import math
import os
import time
from collections import Counter
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.sensing.frames.board import BOARD_COLS, BOARD_ROWS

if TYPE_CHECKING:
    from serial import SerialBase

READ_TIMEOUT_S = 0.05  # a read returns after this long without data (deadline checks)
MAX_LINE_BYTES = 65536  # a line longer than this is garbage: dropped and counted


class PortClosed(FrameError):
    """The port vanished while reading (cable unplugged, pseudo-terminal closed)."""


def open_port(port: str, baud: int = 115200, timeout_s: float = READ_TIMEOUT_S) -> SerialBase:
    """Open `port` 8N1 with pyserial (``serial_for_url``: device paths and URLs)."""
    import serial

    try:
        return serial.serial_for_url(
            port,
            baudrate=baud,
            bytesize=8,
            parity="N",
            stopbits=1,
            timeout=timeout_s,
            exclusive=True,
        )
    except (serial.SerialException, OSError, ValueError) as exc:
        code = getattr(exc, "errno", None)
        text = str(exc)
        if (
            code == errno.ENOENT
            or "No such file" in text
            or "could not open port" in text
            and "No such" in text
        ):
            raise FrameError(f"{port}: serial port does not exist") from None
        if code in (errno.EBUSY, errno.EAGAIN) or "lock" in text or "busy" in text.lower():
            raise FrameError(f"{port}: serial port is busy (another program has it open)") from None
        raise FrameError(f"{port}: cannot open serial port: {text}") from None


def read_chunk(port: SerialBase, name: str) -> bytes:
    """What the port has (b"" after a timeout); a vanished port raises PortClosed. Bytes
    already waiting on a device port are taken with one read(2) (pyserial's read adds a
    select loop and a timer: a tenth of a millisecond per line in the live loop)."""
    import serial

    try:
        n = port.in_waiting
        fd = getattr(port, "fd", None)
        if n and isinstance(fd, int):
            data = os.read(fd, n)
            if not data:
                raise serial.SerialException("the port reported data but returned none")
            return data
        return port.read(max(1, n))
    except (serial.SerialException, OSError, TypeError) as exc:
        raise PortClosed(f"{name}: port closed or unplugged ({exc})") from None


class LineReader:
    """Complete text lines from a port; a partial line at the end is counted as cut."""

    def __init__(self, port: SerialBase, name: str = "port"):
        self.port, self.name = port, name
        self.buf = bytearray()
        self.cut = 0

    def poll(self) -> list[str]:
        """Lines completed since the last call ([] after a timeout without data)."""
        try:
            chunk = read_chunk(self.port, self.name)
        except PortClosed:
            if self.buf:
                self.cut += 1
                self.buf.clear()
            raise
        if not chunk:
            return []
        self.buf += chunk
        parts = self.buf.split(b"\n")
        self.buf = bytearray(parts.pop())
        if len(self.buf) > MAX_LINE_BYTES:
            self.buf.clear()
            self.cut += 1
        return [p.decode("ascii", errors="replace").rstrip("\r") for p in parts]


class FrameReader:
    """MuCa frames (R, C) counts from a port, stamped with host time (s), in the firmware's
    ASCII or binary format (`fmt`: auto, ascii, binary; `muca_formats`)."""

    def __init__(
        self,
        port: SerialBase,
        rows: int = BOARD_ROWS,
        cols: int = BOARD_COLS,
        name: str = "port",
        fmt: str = "auto",
    ):
        from fruitcli.sensing.frames.muca import make_decoder

        self.port, self.name = port, name
        self.rows, self.cols = rows, cols
        self.decoder = make_decoder(fmt, rows, cols)
        self.decoder_bytes = 0
        self.t0 = time.monotonic()

    @property
    def format(self) -> str | None:
        """ "ascii" or "binary" once known (None while auto-detection waits)."""
        return self.decoder.format

    @property
    def skipped(self) -> int:
        """Lines (ASCII) or damaged packets (binary) skipped."""
        return self.decoder.skipped

    @property
    def cut(self) -> int:
        return self.decoder.cut

    @property
    def wrong_size(self) -> Counter:
        """ASCII lines of another field count, per count (empty for binary)."""
        return self.decoder.wrong_size

    def skip_reasons(self) -> str:
        """Why lines or bytes were skipped, e.g. "252 lines of 252 counts, expected 240 =
        20 x 12"; "" when none was."""
        return self.decoder.skip_reasons()

    def _stamp(self, frames: list[np.ndarray]) -> list[tuple[np.ndarray, float, int]]:
        t = time.monotonic() - self.t0
        return list(zip(frames, [t] * len(frames), self.decoder.starts, strict=True))

    @property
    def bytes_read(self) -> int:
        """Bytes taken from the port so far (the stream offset of the next byte)."""
        return self.decoder_bytes

    def poll(self) -> list[tuple[np.ndarray, float, int]]:
        """Frames completed since the last call: (counts (R, C), t_s, stream offset of the
        frame's first byte)."""
        chunk = read_chunk(self.port, self.name)
        if not chunk:
            return []
        self.decoder_bytes += len(chunk)
        return self._stamp(self.decoder.feed(chunk))

    def finish(self) -> list[tuple[np.ndarray, float, int]]:
        """Frames still held when the stream ends (binary: the last packet)."""
        return self._stamp(self.decoder.finish())


def parse_pressure_line(line: str) -> dict[str, float] | None:
    """``P c1=2.5 c2=0.0`` -> {"c1": 2.5, "c2": 0.0} (kPa); None if not a pressure line."""
    parts = line.strip().split()
    if len(parts) < 2 or parts[0] != "P":
        return None
    out = {}
    for p in parts[1:]:
        name, sep, value = p.partition("=")
        if not sep or not name:
            return None
        try:
            v = float(value)
        except ValueError:
            return None
        if not math.isfinite(v):
            return None
        out[name] = v
    return out


class PressureState:
    """Latest chamber pressures (kPa) in a fixed chamber order, updated from lines, with
    the host monotonic time (s) of the line that set them (NaN before the first)."""

    def __init__(self, chambers: tuple[str, ...]):
        self.chambers = chambers
        self.kpa = np.zeros(len(chambers))
        self.latest = (self.kpa, math.nan)  # (kPa, monotonic s): read as one tuple
        self.skipped = 0
        self.received = 0  # pressure lines taken
        self.closed = False  # the pressure port closed (the last pressures stay)

    def update(self, line: str, t_monotonic: float | None = None) -> None:
        got = parse_pressure_line(line)
        if got is None or any(c not in self.chambers for c in got):
            self.skipped += 1
            return
        kpa = self.kpa.copy()
        for c, v in got.items():
            kpa[self.chambers.index(c)] = v
        t = time.monotonic() if t_monotonic is None else t_monotonic
        self.kpa = kpa  # one assignment: readers see old or new, never half
        self.latest = (kpa, t)
        self.received += 1
