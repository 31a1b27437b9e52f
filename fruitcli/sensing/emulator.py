"""A MuCa board on a pseudo-terminal: plays frames in the board's ASCII format.

Units: counts, frames/s. Lines end with ``\\r\\n`` (Arduino ``println``); the board's log
lines (``[Muca] Set TEST mode``...) come first and can be mixed in between frames.
"""

from __future__ import annotations

import fcntl
import os
import struct
import termios
import threading
import time
import tty

import numpy as np

from fruitcli.sensing.frames_io import format_line

BANNER = ("[Muca] Init", "[Muca] Set TEST mode", "[Muca] Gain set to 10")
DRAIN_TIMEOUT_S = 2.0  # wait this long for a reader to take the last bytes before closing
READER_TIMEOUT_S = 10.0  # wait_for_reader gives up after this long and plays anyway
NO_READER_S = 5.0  # nothing taken from the port for this long: the reader has gone, stop
READER_SETTLE_S = 0.1  # pyserial flushes the input right after configuring the port
_POLL_S = 0.01
_DRAIN_EMPTY_POLLS = 5  # consecutive empty polls that mean drained


def synthetic_frames(n: int, seed: int = 0, rows: int = 21, cols: int = 12) -> np.ndarray:
    """Idle board (500 counts, noise std 1) with one touch (60 counts, sigma 0.8 cells)
    sweeping diagonally during the middle half of the `n` frames."""
    rng = np.random.default_rng(seed)
    frames = 500 + rng.normal(0, 1.0, (n, rows, cols))
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    for k in range(n // 4, 3 * n // 4):
        u = (k - n // 4) / max(n // 2, 1)
        r0, c0 = 2 + u * (rows - 5), 2 + u * (cols - 5)
        frames[k] += 60 * np.exp(-((r - r0) ** 2 + (c - c0) ** 2) / (2 * 0.8 ** 2))
    return np.maximum(np.round(frames), 0).astype(np.int64)


class _ReaderGone(Exception):
    """Nothing was read from the port for NO_READER_S (or stop was set while full)."""


class BoardEmulator:
    """Open a pty, then `play()` frames on it (in a thread or the main thread).

    `wait_for_reader` holds the stream until a reader configures the port (pyserial sets
    its baud rate on open, then flushes the input), so no frame is sent into the void;
    `log_every` mixes a log line after every that many frames; `cut_at` frame indices
    are sent cut in the middle (half a line, then ``\\r\\n``); `vanish_after` closes the
    port (like an unplugged cable) in the middle of the next frame's line;
    `time_scale` plays `fps` emulated frames per second that many times faster (the
    compressed-time soak test, `fruitcli.sensing.soak`).
    """

    def __init__(self, frames: np.ndarray, fps: float = 60.0, log_every: int = 0,
                 cut_at=(), vanish_after: int | None = None, wait_for_reader: bool = False,
                 time_scale: float = 1.0):
        self.frames = np.asarray(frames)
        self.fps = fps * time_scale
        self.log_every = log_every
        self.cut_at = set(cut_at)
        self.vanish_after = vanish_after
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self._attrs = termios.tcgetattr(self.slave)
        self.wait_for_reader = wait_for_reader
        self.path = os.ttyname(self.slave)
        self.stop = threading.Event()
        self.sent = 0  # whole frames sent
        self.reader_gone = False  # play() stopped: nothing was taken for NO_READER_S
        os.set_blocking(self.master, False)  # a full port must not block play() forever

    def _write(self, text: str) -> None:
        """Write all of text; raise _ReaderGone when the port stays full NO_READER_S."""
        data = text.encode("ascii")
        stalled = None
        while data:
            try:
                n = os.write(self.master, data)
            except BlockingIOError:
                n = 0
            if n:
                data, stalled = data[n:], None
                continue
            stalled = stalled or time.monotonic()
            if self.stop.is_set() or time.monotonic() - stalled > NO_READER_S:
                raise _ReaderGone
            time.sleep(_POLL_S)

    def play(self) -> int:
        """Send the banner and the frames at `fps`; close the port. -> frames sent whole."""
        try:
            if self.wait_for_reader:
                self._await_reader()
            for line in BANNER:
                self._write(line + "\r\n")
            t0 = time.monotonic()
            for k, frame in enumerate(self.frames):
                if self.stop.is_set():
                    break
                if self.vanish_after is not None and k >= self.vanish_after:
                    line = format_line(frame)
                    self._write(line[: len(line) // 2])  # unplugged in mid-line
                    break
                if self.fps > 0:
                    delay = t0 + k / self.fps - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
                line = format_line(frame)
                if k in self.cut_at:
                    self._write(line[: len(line) // 2] + "\r\n")
                else:
                    self._write(line + "\r\n")
                    self.sent += 1
                if self.log_every and (k + 1) % self.log_every == 0:
                    self._write(f"Calibration performed {(k // self.log_every) % 20 + 1}/20\r\n")
            self._drain()
        except _ReaderGone:
            self.reader_gone = not self.stop.is_set()
        except OSError:
            pass  # the reader side went away
        finally:
            self.close()
        return self.sent

    def _await_reader(self) -> None:
        end = time.monotonic() + READER_TIMEOUT_S
        while time.monotonic() < end and not self.stop.is_set():
            if termios.tcgetattr(self.slave) != self._attrs:
                time.sleep(READER_SETTLE_S)
                return
            time.sleep(_POLL_S)

    def _drain(self) -> None:
        """Wait until the reader has taken what was written (or a timeout). Bytes reach the
        slave's queue through the kernel's flip buffer with some delay, so the queue must
        stay empty over a few polls."""
        end = time.monotonic() + DRAIN_TIMEOUT_S
        empty = 0
        while time.monotonic() < end and not self.stop.is_set() and empty < _DRAIN_EMPTY_POLLS:
            time.sleep(_POLL_S)
            pending = struct.unpack("i", fcntl.ioctl(self.slave, termios.FIONREAD,
                                                     b"\0\0\0\0"))[0]
            empty = empty + 1 if pending == 0 else 0

    def close(self) -> None:
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass
        self.master = self.slave = -1

    def start(self) -> threading.Thread:
        """Play in a daemon thread; returns it."""
        th = threading.Thread(target=self.play, daemon=True)
        th.start()
        return th
