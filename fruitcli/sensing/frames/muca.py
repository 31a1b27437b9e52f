"""The stock MuCa firmware's two raw-frame formats, decoded from a byte stream.

Units: counts. Frames are (rows, cols) with rows = Tx lines, cols = Rx lines, Tx-major
(cell k is Tx k // cols, Rx k % cols); `skipLine` in the firmware gives fewer of either.

ASCII (example ``Muca_Raw``): one line per frame, rows*cols comma-separated counts, CR LF.
Start-up lines (``[Muca] Set TEST mode``, ``[Muca] Gain set to 2``) come first and again
after every reset; they and cut lines are skipped and counted (`frames_io.parse_line`).

Binary (``SendRawByte`` in ``Muca_Raw_Basic``): packets of 2 + rows*cols bytes, nothing
between them: bytes 0-1 the big-endian minimum over the cells with a positive count, then
each cell's count minus that minimum as one unsigned byte. Decoded count = minimum + byte,
exact for frames whose counts are all positive and spread over at most 255 counts (wider
frames wrap in the firmware itself; zero cells cannot be told apart).

Finding and keeping the packet boundary (there is no delimiter and no checksum). At the
true boundary: (a) some data byte is 0 (the cell at the minimum); (b) consecutive packets
agree: the median over the cells of |count change| is at most ``MAX_MEDIAN_STEP_COUNTS``
and the minimum moves by at most ``MAX_MIN_STEP_COUNTS`` (noise moves counts by a few;
a touch raises a few cells and leaves the minimum alone: an assumption, the paper's
touches raise C above C0). A boundary shifted by a byte turns a header byte into a count
and a count into a header byte, so its counts jump by multiples of 256 whenever the
minimum's low byte or a count changes.
Unsynchronized, the decoder scores every offset of one packet length over
``SYNC_PACKETS`` packets; of the offsets whose packets all satisfy (a) and (b) it takes
the one whose counts vary least (the true boundary's vary by noise alone); bytes before
it are skipped (start-up lines, a reset's text). Synchronized, packet k is passed on when
it agrees with packet k - 1 and the next packet's header, read where it must begin,
agrees with k's minimum. A lost or extra byte in packet k moves that header: k is
dropped, and the decoder resynchronizes from there. Cost: the frame the byte falls in,
and also the frame before when the byte is one of the packet's two header bytes (the
previous packet then finds no valid header after it); each resynchronization needs
``SYNC_PACKETS`` packets, which are all passed on, so nothing else is lost (tested),
as long as the next damage is more than ``SYNC_PACKETS`` packets later; damage within a
synchronization window costs the packets of that window before it.
A board whose counts do not move at all (no noise) cannot be synchronized with
certainty: every offset then looks alike. Latency: a packet waits for the next packet's
two header bytes; after a (re)synchronization the first packets wait for all
``SYNC_PACKETS``. The stream's last packet is passed on at `finish` when it agrees with
the one before.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.sensing.frames.formats import BOARD_FORMATS
from fruitcli.sensing.frames.muca_line import format_line, parse_line

FORMATS = ("auto", *BOARD_FORMATS)  # what a reader accepts: auto-detected or named
HEADER_BYTES = 2
MAX_MEDIAN_STEP_COUNTS = 8  # (b): median |count change| between consecutive packets
MAX_MIN_STEP_COUNTS = 16  # (b): change of the minimum between consecutive packets
SYNC_PACKETS = 8  # packets scored per candidate offset when synchronizing
MIN_FINAL_PACKETS = 3  # ... at the end of a stream, when fewer are left
NO_POSITIVE_MINIMUM = 80000 & 0xFFFF  # the firmware's start value, as a 16-bit unsigned
DECODE_CHUNK_BYTES = 4096  # a capture file is decoded in chunks like a port's reads
MAX_LINE_BYTES = 65536  # a "line" longer than this is garbage: dropped and counted as cut


def check_format(fmt: str, where: str = "--format") -> str:
    if fmt not in FORMATS:
        raise FrameError(f"{where}: expected one of {', '.join(FORMATS)}, got {fmt!r}")
    return fmt


def encode_packet(counts: np.ndarray) -> bytes:
    """One frame as the firmware's SendRawByte packet (2 + rows*cols bytes)."""
    g = np.asarray(counts).ravel().astype(np.int64)
    pos = g[g > 0]
    minimum = (int(pos.min()) if pos.size else NO_POSITIVE_MINIMUM) & 0xFFFF
    data = ((g - minimum) & 0xFF).astype(np.uint8)
    return bytes((minimum >> 8, minimum & 0xFF)) + data.tobytes()


def packet_counts(packet: bytes | bytearray) -> np.ndarray:
    """Counts (rows*cols,) int64 of one packet: minimum + byte."""
    b = np.frombuffer(bytes(packet), dtype=np.uint8)
    return (int(b[0]) << 8 | int(b[1])) + b[HEADER_BYTES:].astype(np.int64)


def format_ascii_line(counts: np.ndarray, trailing_comma: bool = False) -> bytes:
    """One frame as Muca_Raw prints it (CR LF); `trailing_comma` like some sketches do."""
    return (format_line(counts, trailing_comma=trailing_comma) + "\r\n").encode("ascii")


class AsciiDecoder:
    """Frames from the ASCII format; counts why other lines were skipped."""

    format = "ascii"

    def __init__(self, rows: int, cols: int):
        self.rows, self.cols = rows, cols
        self.buf = bytearray()
        self.skipped = 0  # lines skipped
        self.cut = 0  # partial lines dropped (too long, or at the end)
        self.board_lines = 0  # lines without a comma ([Muca] ..., Calibration ...)
        self.wrong_size: Counter[int] = Counter()  # field count -> lines
        self.bad_values = 0
        self.last_bad_value = ""
        self.shifted = 0  # one field too many and no host timestamp in front
        self.bytes = 0  # fed so far
        self.starts: list[int] = []  # stream offsets of the frames last returned
        # the compiled fast path (`ascii_kernel.plain_counts`), loaded on the first line
        self._plain: Callable[[np.ndarray, np.ndarray], bool] | None = None

    def feed(self, chunk: bytes) -> list[np.ndarray]:
        """Frames completed by `chunk`; `self.starts` gets their stream offsets."""
        self.bytes += len(chunk)
        self.buf += chunk
        at = self.bytes - len(self.buf)  # stream offset of buf[0]
        parts = self.buf.split(b"\n")
        self.buf = bytearray(parts.pop())
        if len(self.buf) > MAX_LINE_BYTES:
            self.buf.clear()
            self.cut += 1
        out, self.starts = [], []
        for p in parts:
            got = self.plain(p)
            if got is None:
                got = self.line(p.decode("ascii", errors="replace").rstrip("\r"))
            if got is not None:
                out.append(got)
                self.starts.append(at)
            at += len(p) + 1
        return out

    def plain(self, raw: bytes | bytearray) -> np.ndarray | None:
        """The frame of a line of digits and commas only (`ascii_kernel`), else None."""
        if self._plain is None:
            from fruitcli.sensing.frames.ascii_kernel import plain_counts

            self._plain = plain_counts
        counts = np.empty(self.rows * self.cols, np.int64)
        if len(raw) < counts.size or not self._plain(np.frombuffer(raw, np.uint8), counts):
            return None
        return counts.reshape(self.rows, self.cols)

    def line(self, line: str) -> np.ndarray | None:
        counts, _, why = parse_line(line, self.rows * self.cols)
        if counts is not None:
            return counts.reshape(self.rows, self.cols)
        self.skipped += 1
        if why.startswith("value"):
            self.bad_values += 1
            self.last_bad_value = why[7:]
        elif why.startswith("shifted"):
            self.shifted += 1
        elif "," not in line:
            self.board_lines += 1
        else:
            self.wrong_size[len(line.strip().split(","))] += 1
        return None

    def finish(self) -> list[np.ndarray]:
        if self.buf.strip():
            self.cut += 1
        self.buf.clear()
        self.starts = []
        return []

    def skip_reasons(self) -> str:
        """Why lines were skipped, e.g. "252 lines of 252 counts, expected 240 = 20 x 12"."""
        n_cells = self.rows * self.cols
        parts = []
        common = self.wrong_size.most_common(2)
        for n, k in common:
            parts.append(
                f"{k} line{'s' * (k != 1)} of {n} counts, expected {n_cells} = "
                f"{self.rows} x {self.cols}"
            )
        rest = sum(self.wrong_size.values()) - sum(k for _, k in common)
        if rest:
            parts.append(f"{rest} other line{'s' * (rest != 1)} of another size")
        if self.bad_values:
            parts.append(f"{self.bad_values} with bad values ({self.last_bad_value})")
        if self.shifted:
            parts.append(
                f"{self.shifted} of {n_cells + 1} fields without a host timestamp "
                "in front (shifted counts refused)"
            )
        if self.board_lines:
            parts.append(f"{self.board_lines} board log line{'s' * (self.board_lines != 1)}")
        return "; ".join(parts)


class BinaryDecoder:
    """Frames from SendRawByte packets, with the packet boundary found and kept (module
    docstring)."""

    format = "binary"

    def __init__(self, rows: int, cols: int):
        self.rows, self.cols = rows, cols
        self.size = HEADER_BYTES + rows * cols
        self.buf = bytearray()
        self.synced = False
        self.prev: np.ndarray | None = None  # counts of the last packet passed on
        self.skipped = 0  # packets dropped after synchronization (damaged)
        self.skipped_bytes = 0  # bytes outside packets (start-up lines, resets, damage)
        self.syncs = 0  # times the boundary was found (1 + resynchronizations)
        self.bytes = 0  # fed so far
        self.starts: list[int] = []  # stream offsets of the frames last returned
        self.cut = 0  # a partial packet left at the end
        self.wrong_size: Counter[int] = Counter()  # (ASCII only; kept empty)

    def _header(self, at: int) -> int:
        return self.buf[at] << 8 | self.buf[at + 1]

    def _counts(self, at: int) -> np.ndarray | None:
        """Counts of the packet at `at` in the buffer, None when (a) fails."""
        if 0 not in self.buf[at + HEADER_BYTES : at + self.size]:
            return None
        return packet_counts(self.buf[at : at + self.size])

    @staticmethod
    def agree(a: np.ndarray, b: np.ndarray) -> bool:
        """(b) for two packets' counts (the minimum is counts.min() when (a) holds)."""
        return (
            abs(int(a.min()) - int(b.min())) <= MAX_MIN_STEP_COUNTS
            and float(np.median(np.abs(a - b))) <= MAX_MEDIAN_STEP_COUNTS
        )

    def _best_offset(self, n: int = SYNC_PACKETS) -> int | None:
        """The offset in [0, size) whose `n` packets satisfy (a) and (b) and vary least;
        None when none does."""
        p = self.size
        raw = np.frombuffer(bytes(self.buf[: p - 1 + n * p]), dtype=np.uint8)
        if raw.size < n * p:
            return None
        win = np.lib.stride_tricks.sliding_window_view(raw, n * p)[:p]
        win = win.reshape(len(win), n, p)
        data = win[:, :, HEADER_BYTES:]
        cand = np.flatnonzero((data == 0).any(axis=2).all(axis=1))  # (a), cheap: first
        if not cand.size:
            return None
        head = win[cand, :, 0].astype(np.int64) << 8 | win[cand, :, 1]
        counts = head[:, :, None] + data[cand]
        step = np.abs(np.diff(counts, axis=1))
        ok = (np.abs(np.diff(head, axis=1)) <= MAX_MIN_STEP_COUNTS).all(axis=1) & (
            np.median(step, axis=2) <= MAX_MEDIAN_STEP_COUNTS
        ).all(axis=1)
        if not ok.any():
            return None
        variation = np.where(ok, step.mean(axis=(1, 2)), np.inf)
        return int(cand[np.argmin(variation)])

    def _sync(self) -> list[np.ndarray] | None:
        """Find the boundary; -> the first SYNC_PACKETS - 1 packets there (the last stays
        in the buffer, to be checked against its successor), or None (need more bytes)."""
        p, n = self.size, SYNC_PACKETS
        while len(self.buf) >= p - 1 + n * p:
            off = self._best_offset()
            if off is None:
                del self.buf[:p]
                self.skipped_bytes += p
                continue
            self.skipped_bytes += off
            del self.buf[:off]
            at = self.bytes - len(self.buf)
            self.starts.extend(at + k * p for k in range(n - 1))
            run = [packet_counts(self.buf[k * p : (k + 1) * p]) for k in range(n - 1)]
            del self.buf[: (n - 1) * p]
            self.synced = True
            self.syncs += 1
            self.prev = run[-1]
            return run
        return None

    def feed(self, chunk: bytes) -> list[np.ndarray]:
        self.bytes += len(chunk)
        self.buf += chunk
        out: list[np.ndarray] = []
        self.starts = []  # stream offsets of the frames returned
        p = self.size
        while True:
            if not self.synced:
                got = self._sync()
                if got is None:
                    break
                out.extend(got)
                continue
            if len(self.buf) < p + HEADER_BYTES:
                break
            this = self._counts(0)
            if (
                this is not None
                and self.prev is not None  # set when synchronized
                and self.agree(self.prev, this)
                and abs(self._header(p) - int(this.min())) <= MAX_MIN_STEP_COUNTS
            ):
                out.append(this)
                self.starts.append(self.bytes - len(self.buf))
                self.prev = this
                del self.buf[:p]
            else:  # damaged packet (a lost or extra byte) or a reset: find the boundary
                self.synced = False
                self.skipped += 1
                self.skipped_bytes += 1
                del self.buf[:1]
        return [c.reshape(self.rows, self.cols) for c in out]

    def finish(self) -> list[np.ndarray]:
        """At the end of the stream: the last packet when whole and agreeing with the one
        before (it has no successor); unsynchronized, a shorter run of at least
        MIN_FINAL_PACKETS agreeing packets."""
        out = []
        self.starts = []
        p = self.size
        at = self.bytes - len(self.buf)
        if self.synced and len(self.buf) >= p:
            c = self._counts(0)
            if c is not None and self.prev is not None and self.agree(self.prev, c):
                out.append(c.reshape(self.rows, self.cols))
                self.starts.append(at)
                del self.buf[:p]
        elif not self.synced:
            n = len(self.buf) // p
            off = self._best_offset(n) if n >= MIN_FINAL_PACKETS else None
            if off is not None:
                self.syncs += 1
                self.skipped_bytes += off
                out = [
                    packet_counts(self.buf[off + k * p : off + (k + 1) * p]).reshape(
                        self.rows, self.cols
                    )
                    for k in range(n)
                ]
                self.starts = [at + off + k * p for k in range(n)]
                del self.buf[: off + n * p]
        if self.buf:
            self.cut += 1
            self.skipped_bytes += len(self.buf)
        self.buf.clear()
        return out

    def skip_reasons(self) -> str:
        parts = []
        if not self.syncs and self.bytes:
            parts.append(
                f"no run of {SYNC_PACKETS} agreeing packets of {self.size} bytes "
                f"(2 + {self.rows} x {self.cols}) in {self.bytes} bytes"
            )
        if self.skipped:
            parts.append(f"{self.skipped} damaged packet{'s' * (self.skipped != 1)} dropped")
        if self.syncs > 1:
            parts.append(f"{self.syncs - 1} resynchronization{'s' * (self.syncs != 2)}")
        if self.skipped_bytes:
            parts.append(
                f"{self.skipped_bytes} bytes outside packets (start-up lines, resets, damage)"
            )
        return "; ".join(parts)


class AutoDecoder:
    """Both decoders on the same bytes until one of them yields a frame; then that one."""

    def __init__(self, rows: int, cols: int):
        self.rows, self.cols = rows, cols
        self.candidates: list[AsciiDecoder | BinaryDecoder] = [
            AsciiDecoder(rows, cols),
            BinaryDecoder(rows, cols),
        ]
        self.chosen: AsciiDecoder | BinaryDecoder | None = None

    @property
    def format(self) -> str | None:
        return None if self.chosen is None else self.chosen.format

    @property
    def starts(self) -> list[int]:
        return (self.chosen or self.candidates[0]).starts

    def _pick(self, results: list[list[np.ndarray]]) -> list[np.ndarray]:
        best = max(range(len(results)), key=lambda k: len(results[k]))
        if results[best]:
            self.chosen = self.candidates[best]
            return results[best]
        return []

    def feed(self, chunk: bytes) -> list[np.ndarray]:
        if self.chosen is not None:
            return self.chosen.feed(chunk)
        return self._pick([d.feed(chunk) for d in self.candidates])

    def finish(self) -> list[np.ndarray]:
        if self.chosen is not None:
            return self.chosen.finish()
        return self._pick([d.finish() for d in self.candidates])

    @property
    def skipped(self) -> int:
        return self.candidates[0].skipped if self.chosen is None else self.chosen.skipped

    @property
    def cut(self) -> int:
        return (self.chosen or self.candidates[0]).cut

    @property
    def wrong_size(self) -> Counter:
        return (self.chosen or self.candidates[0]).wrong_size

    def skip_reasons(self) -> str:
        if self.chosen is not None:
            return self.chosen.skip_reasons()
        a, b = (d.skip_reasons() for d in self.candidates)
        n = self.candidates[0].bytes
        if not n:
            return ""
        return (
            f"neither format found in {n} bytes: ASCII: {a or 'no whole line'}; "
            f"binary: {b or 'too few bytes'}"
        )


def make_decoder(fmt: str, rows: int, cols: int) -> AsciiDecoder | BinaryDecoder | AutoDecoder:
    """AsciiDecoder, BinaryDecoder or AutoDecoder for ``--format`` / ``[board].format``."""
    check_format(fmt)
    decoders: dict[str, type[AsciiDecoder | BinaryDecoder | AutoDecoder]] = {
        "ascii": AsciiDecoder,
        "binary": BinaryDecoder,
        "auto": AutoDecoder,
    }
    return decoders[fmt](rows, cols)


def decode_bytes(
    data: bytes, fmt: str, rows: int, cols: int
) -> tuple[np.ndarray, AsciiDecoder | BinaryDecoder | AutoDecoder]:
    """All frames (N, rows, cols) of a whole capture, and the decoder (its counters)."""
    dec = make_decoder(fmt, rows, cols)
    frames = []
    for k in range(0, len(data), DECODE_CHUNK_BYTES):  # auto-detection commits early
        frames += dec.feed(data[k : k + DECODE_CHUNK_BYTES])
    frames += dec.finish()
    arr = np.stack(frames) if frames else np.zeros((0, rows, cols), np.int64)
    return arr, dec
