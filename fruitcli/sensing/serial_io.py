"""Serial input: MuCa frames and chamber-pressure lines from pyserial ports.

Units: counts, kPa, s (host monotonic time since the port was opened).

A port that does not exist, is busy, or vanishes (unplugged cable, closed pseudo-
terminal) raises `FrameError` with one line naming the port. Lines that are not frames
(board log lines, cut lines, bad values) are skipped and counted, never fatal.

Pressure line protocol (``fruit live --pressure-port``): one ASCII line per reading,
``P <chamber>=<kPa> [<chamber>=<kPa> ...]`` terminated by ``\\n`` (``\\r\\n`` accepted),
e.g. ``P c1=2.5 c2=0.0``. Chambers not named keep their last value (0 kPa at start);
other lines are skipped and counted.
"""

from __future__ import annotations

import errno
import math
import time
from collections import Counter

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.sensing.frames_io import parse_line

READ_TIMEOUT_S = 0.05  # a read returns after this long without data (deadline checks)
MAX_LINE_BYTES = 65536  # a line longer than this is garbage: dropped and counted


class PortClosed(FrameError):
    """The port vanished while reading (cable unplugged, pseudo-terminal closed)."""


def open_port(port: str, baud: int = 115200, timeout_s: float = READ_TIMEOUT_S):
    """Open `port` 8N1 with pyserial (``serial_for_url``: device paths and URLs)."""
    import serial

    try:
        return serial.serial_for_url(port, baudrate=baud, bytesize=8, parity="N",
                                     stopbits=1, timeout=timeout_s, exclusive=True)
    except (serial.SerialException, OSError, ValueError) as exc:
        code = getattr(exc, "errno", None)
        text = str(exc)
        if code == errno.ENOENT or "No such file" in text or "could not open port" in text \
                and "No such" in text:
            raise FrameError(f"{port}: serial port does not exist") from None
        if code in (errno.EBUSY, errno.EAGAIN) or "lock" in text or "busy" in text.lower():
            raise FrameError(f"{port}: serial port is busy (another program has it open)") \
                from None
        raise FrameError(f"{port}: cannot open serial port: {text}") from None


class LineReader:
    """Complete text lines from a port; a partial line at the end is counted as cut."""

    def __init__(self, port, name: str = "port"):
        self.port, self.name = port, name
        self.buf = bytearray()
        self.cut = 0

    def poll(self) -> list[str]:
        """Lines completed since the last call ([] after a timeout without data)."""
        import serial

        try:
            n = max(1, self.port.in_waiting)
            chunk = self.port.read(n)
        except (serial.SerialException, OSError) as exc:
            if self.buf:
                self.cut += 1
                self.buf.clear()
            raise PortClosed(f"{self.name}: port closed or unplugged ({exc})") from None
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
    """MuCa frames (R, C) counts from a port, stamped with host time (s)."""

    def __init__(self, port, rows: int = 21, cols: int = 12, name: str = "port"):
        self.lines = LineReader(port, name)
        self.rows, self.cols = rows, cols
        self.skipped = 0
        self.board_lines = 0  # skipped lines without a comma (board log lines)
        self.wrong_size: Counter[int] = Counter()  # counts per line -> skipped lines
        self.bad_values = 0  # skipped lines with the right size but a bad value
        self.last_bad_value = ""
        self.t0 = time.monotonic()

    def skip_reasons(self) -> str:
        """Why lines were skipped, e.g. "252 lines of 252 counts, expected 240 = 20 x 12";
        "" when none was."""
        n_cells = self.rows * self.cols
        parts = []
        for n, k in self.wrong_size.most_common(2):
            parts.append(f"{k} line{'s' * (k != 1)} of {n} counts, expected {n_cells} = "
                         f"{self.rows} x {self.cols}")
        rest = sum(self.wrong_size.values()) - sum(k for _, k in
                                                   self.wrong_size.most_common(2))
        if rest:
            parts.append(f"{rest} other line{'s' * (rest != 1)} of another size")
        if self.bad_values:
            parts.append(f"{self.bad_values} with bad values ({self.last_bad_value})")
        if self.board_lines:
            parts.append(f"{self.board_lines} board log line{'s' * (self.board_lines != 1)}")
        return "; ".join(parts)

    def poll(self) -> list[tuple[np.ndarray, float, str]]:
        """Frames completed since the last call: (counts (R, C), t_s, raw line)."""
        out = []
        for line in self.lines.poll():
            counts, _, why = parse_line(line, self.rows * self.cols)
            if counts is None:
                self.skipped += 1
                if why.startswith("value"):
                    self.bad_values += 1
                    self.last_bad_value = why[7:]
                elif "," not in line:
                    self.board_lines += 1
                else:
                    self.wrong_size[len(line.strip().split(","))] += 1
                continue
            out.append((counts.reshape(self.rows, self.cols), time.monotonic() - self.t0,
                        line))
        return out


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
    """Latest chamber pressures (kPa) in a fixed chamber order, updated from lines."""

    def __init__(self, chambers: tuple[str, ...]):
        self.chambers = chambers
        self.kpa = np.zeros(len(chambers))
        self.skipped = 0
        self.received = 0  # pressure lines taken
        self.closed = False  # the pressure port closed (the last pressures stay)

    def update(self, line: str) -> None:
        got = parse_pressure_line(line)
        if got is None or any(c not in self.chambers for c in got):
            self.skipped += 1
            return
        kpa = self.kpa.copy()
        for c, v in got.items():
            kpa[self.chambers.index(c)] = v
        self.kpa = kpa  # one assignment: readers see old or new, never half
        self.received += 1
