"""A MuCa board on a pseudo-terminal: plays frames in the stock firmware's ASCII or binary
format (`fruitcli.sensing.frames.muca`).

Units: counts, frames/s, baud. ASCII lines end with ``\\r\\n`` (Arduino ``println``); the
firmware's start-up lines (``[Muca] Set TEST mode``, ``[Muca] Gain set to 2``) come first
in both formats, and again after a reset. With `baud` the bytes leave no faster than a
real serial line carries them: 8N1 sends 10 bits per byte, so 115200 baud is 11,520
bytes/s (a 21 x 12 ASCII frame of ~1,265 bytes: ~9 frames/s; a 254-byte binary packet:
~45 frames/s). A pseudo-terminal itself has no baud rate: this pacing is the emulator's.
"""

from __future__ import annotations

import fcntl
import itertools
import os
import struct
import termios
import threading
import time
import tty
from collections.abc import Callable, Collection

import numpy as np

from fruitcli.sensing.frames.board import BOARD_COLS, BOARD_ROWS
from fruitcli.sensing.frames.muca import check_format, encode_packet, format_ascii_line

BANNER = ("[Muca] Set TEST mode", "[Muca] Gain set to 2")  # init + useRawData, setGain(2)
BITS_PER_BYTE = 10  # 8N1: start bit, 8 data bits, stop bit
PACED_PIECE_BYTES = 16  # paced bytes are written in pieces of this many (or more)
MAX_PACED_WRITES_PER_S = 1000  # ... but no more pieces than this a second
DRAIN_TIMEOUT_S = 2.0  # wait this long for a reader to take the last bytes before closing
READER_TIMEOUT_S = 10.0  # wait_for_reader gives up after this long and plays anyway
NO_READER_S = 5.0  # nothing taken from the port for this long: the reader has gone, stop
READER_SETTLE_S = 0.1  # pyserial flushes the input right after configuring the port
_POLL_S = 0.01
_DRAIN_EMPTY_POLLS = 5  # consecutive empty polls that mean drained


def synthetic_frames(
    n: int, seed: int = 0, rows: int = BOARD_ROWS, cols: int = BOARD_COLS
) -> np.ndarray:
    """Idle board (500 counts, noise std 1) with one touch (60 counts, sigma 0.8 cells)
    sweeping diagonally during the middle half of the `n` frames."""
    rng = np.random.default_rng(seed)
    frames = 500 + rng.normal(0, 1.0, (n, rows, cols))
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    for k in range(n // 4, 3 * n // 4):
        u = (k - n // 4) / max(n // 2, 1)
        r0, c0 = 2 + u * (rows - 5), 2 + u * (cols - 5)
        frames[k] += 60 * np.exp(-((r - r0) ** 2 + (c - c0) ** 2) / (2 * 0.8**2))
    return np.maximum(np.round(frames), 0).astype(np.int64)


class _ReaderGone(Exception):
    """Nothing was read from the port for NO_READER_S (or stop was set while full)."""


def byte_rate(baud: int) -> float:
    """Bytes per second a serial line at `baud` 8N1 carries (0: unpaced)."""
    return baud / BITS_PER_BYTE if baud else 0.0


def frame_bytes(frame: np.ndarray, fmt: str, trailing_comma: bool = False) -> bytes:
    """One frame as the firmware sends it: an ASCII line or a SendRawByte packet."""
    if fmt == "binary":
        return encode_packet(frame)
    return format_ascii_line(frame, trailing_comma)


def pacing_line(
    fmt: str,
    baud: int,
    rows: int = BOARD_ROWS,
    cols: int = BOARD_COLS,
    frames: np.ndarray | None = None,
) -> str:
    """What the pacing means, e.g. "115200 baud 8N1 = 11520 bytes/s: 254-byte binary
    packets, at most 45.4 frames/s"."""
    if not baud:
        return "unpaced (as fast as the reader takes the bytes)"
    if frames is not None and len(frames):
        size = float(np.mean([len(frame_bytes(f, fmt)) for f in frames[:50]]))
    else:
        size = 2 + rows * cols if fmt == "binary" else rows * cols * 4 + 1
    what = "binary packets" if fmt == "binary" else "ASCII lines"
    return (
        f"{baud} baud 8N1 = {byte_rate(baud):g} bytes/s: {size:,.0f}-byte {what}, "
        f"at most {byte_rate(baud) / size:.1f} frames/s"
    )


class BoardEmulator:
    """Open a pty, then `play()` frames on it (in a thread or the main thread).

    `fmt` "ascii" (Muca_Raw) or "binary" (SendRawByte); `baud` paces the bytes like a
    serial line (0: unpaced); `fps` caps the frame rate (0: no cap).
    `wait_for_reader` holds the stream until a reader configures the port (pyserial sets
    its baud rate on open, then flushes the input), so no frame is sent into the void;
    `log_every` mixes a log line after every that many frames (ASCII); `cut_at` frame
    indices are sent cut in the middle (half a line, then ``\\r\\n``; half a packet);
    `lose_byte_at` / `extra_byte_at` frames lose a byte or get one more (in their middle);
    `reset_at` frames are cut by a board reset (half sent, then the start-up lines again);
    `trailing_comma` ends ASCII lines with a comma; `vanish_after` closes the port (like
    an unplugged cable) in the middle of the next frame. `frames` may be a function of
    the frame index returning a frame, or None to end (frames made as they are sent).
    `time_scale` plays `fps` emulated frames per second (and the baud's bytes) that many
    times faster (the compressed-time soak test, `tests/soak_board.py`).
    """

    def __init__(
        self,
        frames: np.ndarray | Callable[[int], np.ndarray | None],
        fps: float = 60.0,
        log_every: int = 0,
        cut_at: Collection[int] = (),
        vanish_after: int | None = None,
        wait_for_reader: bool = False,
        fmt: str = "ascii",
        baud: int = 0,
        lose_byte_at: Collection[int] = (),
        extra_byte_at: Collection[int] = (),
        reset_at: Collection[int] = (),
        trailing_comma: bool = False,
        time_scale: float = 1.0,
    ):
        # k -> frame, or None: the end
        self.source: Callable[[int], np.ndarray | None] | None = None
        self.frames: np.ndarray | None = None
        if callable(frames):
            self.source = frames
        else:
            self.frames = np.asarray(frames)
        self.fps = fps * time_scale
        self.fmt = check_format(fmt)
        if fmt == "auto":
            raise ValueError("the emulator speaks ascii or binary, not auto")
        self.rate = byte_rate(baud) * time_scale
        self.log_every = log_every
        self.cut_at = set(cut_at)
        self.lose_byte_at, self.extra_byte_at = set(lose_byte_at), set(extra_byte_at)
        self.reset_at = set(reset_at)
        self.trailing_comma = trailing_comma
        self.vanish_after = vanish_after
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self._attrs = termios.tcgetattr(self.slave)
        self.wait_for_reader = wait_for_reader
        self.path = os.ttyname(self.slave)
        self.stop = threading.Event()
        self.sent = 0  # whole frames sent
        self.bytes_sent = 0
        self.reader_gone = False  # play() stopped: nothing was taken for NO_READER_S
        self._line_free = 0.0  # monotonic time the paced line is free again
        os.set_blocking(self.master, False)  # a full port must not block play() forever

    def _write(self, data: bytes | str) -> None:
        """Write all of data, paced at the byte rate; raise _ReaderGone when the port stays
        full NO_READER_S."""
        if isinstance(data, str):
            data = data.encode("ascii")
        if self.rate:  # in pieces, each when the line has carried the one before
            piece = max(PACED_PIECE_BYTES, int(self.rate / MAX_PACED_WRITES_PER_S))
            for k in range(0, len(data), piece):
                delay = self._line_free - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
                chunk = data[k : k + piece]
                self._line_free = max(self._line_free, time.monotonic()) + len(chunk) / self.rate
                self._write_now(chunk)
            return
        self._write_now(data)

    def _write_now(self, data: bytes) -> None:
        stalled = None
        while data:
            try:
                n = os.write(self.master, data)
            except BlockingIOError:
                n = 0
            if n:
                data, stalled = data[n:], None
                self.bytes_sent += n
                continue
            stalled = stalled or time.monotonic()
            if self.stop.is_set() or time.monotonic() - stalled > NO_READER_S:
                raise _ReaderGone
            time.sleep(_POLL_S)

    def _banner(self) -> None:
        for line in BANNER:
            self._write(line + "\r\n")

    def play(self) -> int:
        """Send the start-up lines and the frames; close the port. -> frames sent whole."""
        try:
            if self.wait_for_reader:
                self._await_reader()
            self._banner()
            t0 = time.monotonic()
            for k in itertools.count():
                if self.source is not None and self.rate:  # made when the line is free
                    time.sleep(max(0.0, self._line_free - time.monotonic()))
                frame = self._frame(k)
                if frame is None or self.stop.is_set():
                    break
                data = frame_bytes(frame, self.fmt, self.trailing_comma)
                half = len(data) // 2
                if self.vanish_after is not None and k >= self.vanish_after:
                    self._write(data[:half])  # unplugged in mid-frame
                    break
                if self.fps > 0:
                    delay = t0 + k / self.fps - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
                if k in self.reset_at:
                    self._write(data[:half])
                    self._banner()
                elif k in self.cut_at:
                    self._write(data[:half] + (b"\r\n" if self.fmt == "ascii" else b""))
                elif k in self.lose_byte_at:
                    self._write(data[:half] + data[half + 1 :])
                elif k in self.extra_byte_at:
                    self._write(data[:half] + b"\x07" + data[half:])
                else:
                    self._write(data)
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

    def _frame(self, k: int) -> np.ndarray | None:
        if self.source is not None:
            return self.source(k)
        assert self.frames is not None  # the frames, when not a function
        return self.frames[k] if k < len(self.frames) else None

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
            pending = struct.unpack("i", fcntl.ioctl(self.slave, termios.FIONREAD, b"\0\0\0\0"))[0]
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
