"""The Marlin/RepRap host protocol over a serial port: one command at a time.

Units: mm, mm/min, s. What a printer host does (as OctoPrint, Pronterface do):
- after the port opens the board resets and prints ``start`` and ``echo:`` lines;
  `wait_ready` waits for ``start`` (or for the port to stay quiet, a printer that did
  not reset), then sends ``M110 N0`` to start the line numbers;
- every command goes out as ``N<n> <command>*<checksum>`` (checksum: the XOR of every
  byte before ``*``) and the host waits for its ``ok`` before the next one; a time-out
  without ``ok`` is an error naming the command; ``echo:busy: processing`` (homing,
  heating) restarts the time-out;
- ``Resend: <n>`` (after ``Error:checksum mismatch`` or ``Error:Line Number is not Last
  Line Number+1``) sends line n again, up to ``MAX_RESENDS`` times;
- any other ``Error:`` line (``Error:Printer halted. kill() called!``, a thermal error)
  means the printer stopped: `PrinterHalted`;
- ``M114`` reports ``X:.. Y:.. Z:.. E:.. Count ...``; `position` parses it.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from fruitcli.errors import FruitError

if TYPE_CHECKING:
    from serial import SerialBase

READY_TIMEOUT_S = 10.0  # wait this long for "start" after opening the port
QUIET_S = 2.0  # ... or for the port to stay quiet this long (no reset on open)
MAX_RESENDS = 5  # of one line before giving up
COMM_ERRORS = ("checksum", "line number", "no checksum", "no line number", "format error")
_POS = re.compile(r"X:\s*(-?[\d.]+)\s+Y:\s*(-?[\d.]+)\s+Z:\s*(-?[\d.]+)")


class PrinterError(FruitError):
    """The printer does not answer as a Marlin printer should (time-out, port gone)."""


class PrinterHalted(PrinterError):
    """The printer reported ``Error:`` (halted, kill() called, thermal runaway, ...)."""


class PrinterGone(PrinterError):
    """The printer's port vanished (cable unplugged, pseudo-terminal closed)."""


def checksum(text: str) -> int:
    """XOR of the bytes of `text` (the part of the line before ``*``)."""
    cs = 0
    for b in text.encode("ascii"):
        cs ^= b
    return cs


def numbered(n: int, command: str) -> str:
    """``N<n> <command>*<checksum>``."""
    body = f"N{n} {command}"
    return f"{body}*{checksum(body)}"


class Marlin:
    """One command at a time over an open pyserial port (`port`, named `name`)."""

    def __init__(
        self,
        port: SerialBase,
        name: str = "printer",
        timeout_s: float = 30.0,
        log: Callable[[str], None] | None = None,
    ):
        self.port, self.name, self.timeout_s = port, name, timeout_s
        self.line = 0  # number of the last line sent
        self.sent: dict[int, str] = {}
        self.buf = bytearray()
        self.resends = 0  # lines sent again on the printer's request
        self.busy = 0  # busy lines seen
        self.echo: list[str] = []  # echo: lines (last few)
        self.log = log or (lambda msg: None)

    def _readline(self, deadline: float) -> str | None:
        """The next line, or None when `deadline` (monotonic s) passes first."""
        import serial

        while True:
            k = self.buf.find(b"\n")
            if k >= 0:
                line = bytes(self.buf[:k]).decode("ascii", errors="replace").strip()
                del self.buf[: k + 1]
                return line
            if time.monotonic() >= deadline:
                return None
            try:
                chunk = self.port.read(max(1, self.port.in_waiting))
            except (serial.SerialException, OSError, TypeError) as exc:
                raise PrinterGone(
                    f"{self.name}: printer port closed or unplugged ({exc})"
                ) from None
            self.buf += chunk

    def _write(self, text: str) -> None:
        import termios

        import serial

        try:
            self.port.write((text + "\n").encode("ascii"))
            self.port.flush()
        except (serial.SerialException, OSError, TypeError, termios.error) as exc:
            raise PrinterGone(f"{self.name}: printer port closed or unplugged ({exc})") from None

    def wait_ready(self, timeout_s: float = READY_TIMEOUT_S, quiet_s: float = QUIET_S) -> None:
        """Wait for ``start`` (or `quiet_s` of silence), then reset the line numbers."""
        end = time.monotonic() + timeout_s
        last = time.monotonic()
        while time.monotonic() < end:
            line = self._readline(min(end, last + quiet_s))
            if line is None:
                break  # quiet: a printer that did not reset on open
            last = time.monotonic()
            self._check_error(line, "start-up")
            if line == "start":
                self._drain_echo(0.3)
                break
            if line.startswith("echo:"):
                self.echo = (self.echo + [line])[-5:]
        self.line = 0
        self.sent.clear()
        self.command("M110 N0", numbered_line=0)

    def _drain_echo(self, quiet_s: float) -> None:
        """Read the echo: lines after ``start`` until the port is quiet for `quiet_s`."""
        while True:
            line = self._readline(time.monotonic() + quiet_s)
            if line is None:
                return
            self._check_error(line, "start-up")

    def _check_error(self, line: str, command: str) -> bool:
        """True for a communication error (a Resend follows); raise for any other."""
        if not line.startswith("Error:") and not line.startswith("!!"):
            return False
        text = line.split(":", 1)[-1].strip()
        if line.startswith("Error:") and any(w in text.lower() for w in COMM_ERRORS):
            return True
        raise PrinterHalted(
            f"{self.name}: printer error after {command!r}: {line} (the printer has stopped)"
        )

    def command(
        self, command: str, timeout_s: float | None = None, numbered_line: int | None = None
    ) -> list[str]:
        """Send one command and wait for its ``ok``; -> the lines before the ok."""
        n = self.line + 1 if numbered_line is None else numbered_line
        self.line = n
        self.sent[n] = command
        if len(self.sent) > 64:
            self.sent.pop(min(self.sent))
        self._write(numbered(n, command))
        limit = self.timeout_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + limit
        lines: list[str] = []
        tries: dict[int, int] = {}
        while True:
            line = self._readline(deadline)
            if line is None:
                raise PrinterError(
                    f"{self.name}: no 'ok' for {command!r} within {limit:g} s "
                    "(printer not answering)"
                )
            if line.startswith("ok"):
                return lines
            if line.startswith("echo:busy"):
                self.busy += 1
                deadline = time.monotonic() + limit
                continue
            if self._check_error(line, command):
                continue  # the Resend comes next
            m = re.match(r"(?:Resend|rs)\s*:?\s*N?(\d+)", line)
            if m:
                k = int(m.group(1))
                if k not in self.sent:
                    raise PrinterError(
                        f"{self.name}: the printer asks to resend line {k}, "
                        f"which was not sent (last line {self.line})"
                    )
                tries[k] = tries.get(k, 0) + 1
                if tries[k] > MAX_RESENDS:
                    raise PrinterError(
                        f"{self.name}: line {k} ({self.sent[k]!r}) resent "
                        f"{MAX_RESENDS} times, still refused"
                    )
                self._skip_ok(deadline)
                self.resends += 1
                self.log(f"printer asked to resend line {k}: {self.sent[k]}")
                for j in range(k, n + 1):
                    if j in self.sent:
                        self._write(numbered(j, self.sent[j]))
                deadline = time.monotonic() + limit
                continue
            lines.append(line)

    def _skip_ok(self, deadline: float) -> None:
        """Marlin follows ``Resend:`` with an ``ok`` that belongs to the bad line."""
        line = self._readline(deadline)
        if line is not None and not line.startswith("ok"):
            self.buf[:0] = (line + "\n").encode()

    def position(self) -> tuple[float, float, float]:
        """(x, y, z) mm from M114."""
        for line in self.command("M114"):
            m = _POS.search(line)
            if m:
                x, y, z = (float(v) for v in m.groups())
                return x, y, z
        raise PrinterError(f"{self.name}: M114 gave no 'X:.. Y:.. Z:..' position")

    def move(self, x: float, y: float, z: float, feed_mm_min: float) -> None:
        """Queue an absolute move (G1; G21/G90 must have been sent)."""
        self.command(f"G1 X{x:.3f} Y{y:.3f} Z{z:.3f} F{feed_mm_min:.0f}")

    def finish_moves(self, timeout_s: float | None = None) -> None:
        """M400: returns once every queued move is done."""
        self.command("M400", timeout_s)
