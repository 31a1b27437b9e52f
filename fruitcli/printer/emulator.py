"""A Marlin-like printer on a pseudo-terminal, for running the bench without hardware.

Units: mm, mm/min, s. It answers as Marlin 2 does: ``start`` and ``echo:`` lines once a
host opens the port; ``ok`` for every command; numbered lines ``N<n> <cmd>*<cs>`` checked
(checksum, line number), a bad one answered ``Error:...``, ``Resend: <n>``, ``ok``;
``G28`` and ``M400`` print ``echo:busy: processing`` while they take; ``G0``/``G1`` are queued and
take distance / feed rate (times `time_scale`), clamped to the bed like Marlin's
software endstops; ``M400`` answers once every move is done; ``M114`` reports the
planned position. Faults for tests (`faults`, by the count of command lines received):
``resend`` (answer that line as a checksum mismatch, once), ``no-ok`` (never answer it),
``halt`` (answer ``Error:Printer halted. kill() called!`` and nothing more).
"""

from __future__ import annotations

import os
import re
import termios
import threading
import time
import tty
from collections.abc import Callable, Sequence

import numpy as np

from fruitcli.printer.marlin import checksum

BANNER = (
    "start",
    "echo:Marlin 2.1.2 (fruit emulate-printer)",
    "echo: Last Updated: 2023-01-01 | Author: fruit",
    "echo: Free Memory: 4096",
)
HOME_S = 1.2  # homing takes this long
BUSY_EVERY_S = 0.5  # echo:busy: processing while homing or waiting in M400 (Marlin's
# host keepalive; its default interval is 2 s)
FAULTS = ("resend", "no-ok", "halt")
_WORD = re.compile(r"([A-Z])(-?[\d.]+)")


class PrinterEmulator:
    """Open a pty; `start()` answers on it in a thread. The tip position (printer mm) at
    any moment is `tip_mm()`."""

    def __init__(
        self,
        bed_mm: Sequence[float] = (0, 0, 0, 220, 220, 250),
        start_mm: Sequence[float] = (0.0, 0.0, 0.0),
        time_scale: float = 1.0,
        faults: dict | None = None,
        log: Callable[[str], None] | None = None,
    ):
        self.bed = np.asarray(bed_mm, float)
        self.time_scale = time_scale
        self.faults = {k: set(v) for k, v in (faults or {}).items()}
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self._attrs = termios.tcgetattr(self.slave)
        self.path = os.ttyname(self.slave)
        self.stop = threading.Event()
        self.lock = threading.Lock()
        self.planned = np.asarray(start_mm, float)  # where the queued moves end
        self.moves: list[tuple[float, float, np.ndarray, np.ndarray]] = []  # t0, t1, a, b
        self.feed = 1200.0
        self.relative = False
        self.last_line = 0
        self.received = 0  # command lines received
        self.halted = False
        self.clamped = 0  # moves clamped to the bed
        self.log = log or (lambda msg: None)

    # --- the tip over time -------------------------------------------------------------
    def tip_mm(self, t: float | None = None) -> np.ndarray:
        """Tip position (3,) mm at monotonic time `t` (now), along the queued moves."""
        t = time.monotonic() if t is None else t
        with self.lock:
            pos = None
            for t0, t1, a, b in self.moves:
                if t < t0:
                    return a.copy() if pos is None else pos
                if t < t1:
                    return a + (b - a) * (t - t0) / (t1 - t0)
                pos = b
            return self.planned.copy()

    def _queue(self, target: np.ndarray) -> None:
        with self.lock:
            now = time.monotonic()
            start = max(now, self.moves[-1][1]) if self.moves else now
            self.moves = [m for m in self.moves if m[1] > now - 1.0]
            dist = float(np.linalg.norm(target - self.planned))
            dt = dist / (self.feed / 60.0) * self.time_scale if dist else 0.0
            self.moves.append((start, start + dt, self.planned.copy(), target.copy()))
            self.planned = target.copy()

    def _moves_done_at(self) -> float:
        with self.lock:
            return self.moves[-1][1] if self.moves else 0.0

    # --- the serial side ---------------------------------------------------------------
    def _send(self, text: str) -> None:
        os.write(self.master, (text + "\n").encode("ascii"))

    def start(self) -> threading.Thread:
        th = threading.Thread(target=self.run, daemon=True)
        th.start()
        return th

    def run(self) -> None:
        try:
            self._await_reader()
            for line in BANNER:
                self._send(line)
            buf = bytearray()
            while not self.stop.is_set():
                try:
                    chunk = os.read(self.master, 4096)
                except BlockingIOError:
                    chunk = b""
                if not chunk:
                    time.sleep(0.002)
                    continue
                buf += chunk
                while b"\n" in buf:
                    k = buf.index(b"\n")
                    line = bytes(buf[:k]).decode("ascii", errors="replace").strip()
                    del buf[: k + 1]
                    if line:
                        self._handle(line)
        except OSError:
            pass  # the port was closed
        finally:
            self.close()

    def _await_reader(self) -> None:
        os.set_blocking(self.master, False)
        while not self.stop.is_set():
            if termios.tcgetattr(self.slave) != self._attrs:
                time.sleep(0.1)  # pyserial flushes the input right after configuring
                return
            time.sleep(0.01)

    def _handle(self, line: str) -> None:
        if self.halted:
            return
        self.received += 1
        k = self.received
        if k in self.faults.get("halt", ()):
            self.halted = True
            self._send("Error:Printer halted. kill() called!")
            return
        m = re.fullmatch(r"N(\d+)\s+(.*?)\*(\d+)", line)
        if m:
            n, cmd, cs = int(m.group(1)), m.group(2).strip(), int(m.group(3))
            body = line[: line.rindex("*")]
            bad_sum = checksum(body) != cs or k in self.faults.get("resend", ())
            if k in self.faults.get("resend", ()):
                self.faults["resend"].discard(k)
            if bad_sum:
                self._send(f"Error:checksum mismatch, Last Line: {self.last_line}")
                self._send(f"Resend: {self.last_line + 1}")
                self._send("ok")
                return
            if cmd.startswith("M110"):
                self.last_line = n
            elif n != self.last_line + 1:
                self._send(
                    f"Error:Line Number is not Last Line Number+1, Last Line: {self.last_line}"
                )
                self._send(f"Resend: {self.last_line + 1}")
                self._send("ok")
                return
            self.last_line = n
        else:
            cmd = line.split(";")[0].strip()
        reply = self._command(cmd)
        if k in self.faults.get("no-ok", ()):
            return
        for r in reply:
            self._send(r)
        self._send("ok")

    def _command(self, cmd: str) -> list[str]:
        """Carry out one command; -> lines to print before its ok."""
        parts = cmd.split()
        code = parts[0].upper() if parts else ""
        words = {w: float(v) for w, v in _WORD.findall(" ".join(parts[1:]).upper())}
        if code in ("G0", "G1"):
            if "F" in words and words["F"] > 0:
                self.feed = words["F"]
            target = self.planned.copy()
            for axis, i in (("X", 0), ("Y", 1), ("Z", 2)):
                if axis in words:
                    target[i] = target[i] + words[axis] if self.relative else words[axis]
            clamped = np.clip(target, self.bed[:3], self.bed[3:])
            if not np.array_equal(clamped, target):
                self.clamped += 1  # Marlin's software endstops
            self._queue(clamped)
            return []
        if code == "G28":
            return self._home()
        if code == "M400":  # waits for the moves, with Marlin's host keepalive lines
            last = time.monotonic()
            while time.monotonic() < self._moves_done_at() and not self.stop.is_set():
                time.sleep(0.002)
                if time.monotonic() - last >= BUSY_EVERY_S:
                    self._send("echo:busy: processing")
                    last = time.monotonic()
            return []
        if code == "M114":
            x, y, z = self.planned
            return [
                f"X:{x:.2f} Y:{y:.2f} Z:{z:.2f} E:0.00 Count X:{round(x * 80)} "
                f"Y:{round(y * 80)} Z:{round(z * 400)}"
            ]
        if code == "G90":
            self.relative = False
        elif code == "G91":
            self.relative = True
        elif code == "M105":
            return ["T:22.0 /0.0 B:22.0 /0.0"]
        elif code not in ("G21", "M110", "M84", "M211", "M118", "M82", "M83", "G4"):
            return [f'echo:Unknown command: "{cmd}"']
        return []

    def _home(self) -> list[str]:
        end = time.monotonic() + HOME_S * min(1.0, self.time_scale * 10)
        while time.monotonic() < end and not self.stop.is_set():
            time.sleep(min(BUSY_EVERY_S, max(0.0, end - time.monotonic())))
            if time.monotonic() < end:
                self._send("echo:busy: processing")
        with self.lock:
            self.planned = self.bed[:3].copy()
            self.moves = []
        return []

    def close(self) -> None:
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass
        self.master = self.slave = -1
