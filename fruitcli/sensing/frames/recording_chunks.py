"""A recording read chunk by chunk: its frames are never all in memory at once.

Units: counts, seconds, kPa.

An `.npz` recording's ``frames`` member is read in place: its npy header gives the
shape and dtype, then chunks of whole frames are read straight from the file when the
member is stored (as `np.savez` writes it) or through `zipfile` when it is compressed.
Every member's CRC-32 is checked when the recording is opened (`check_zip`), or, with
``verify="read"`` (one pass over the file instead of two), the small members' then and
the stored frames member's as its frames are read in order: the reader calls
`ChunkedRecording.verify` after reading them all (frames read out of order, or not
all, are checked there in a second pass).
Each chunk is checked like a whole recording (`check_frames`: integers >= 0; an error
names the frame's index in the recording). The other keys (t_s, pressures, bench
samples, printer positions, meta) are small and read whole. A MuCa log or a raw board
capture is read whole and served in chunks.
"""

from __future__ import annotations

import functools
import io
import os
import struct
import threading
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.sensing.frames.board import BOARD_COLS, BOARD_ROWS
from fruitcli.sensing.frames.recording import (
    Recording,
    check_frames,
    npz_extras,
    read_recording,
)
from fruitcli.tables import check_zip

if TYPE_CHECKING:
    from fruitcli.scene import BoardSection

_LOCAL_HEADER = struct.Struct("<4s5H3L2H")  # zip local file header (30 bytes)
_LOCAL_MAGIC = b"PK\x03\x04"


@dataclass
class ChunkedRecording:
    """A recording's small arrays, and its frames served by `read` and `chunks`."""

    path: Path
    n_frames: int
    frame_shape: tuple[int, int]
    t_s: np.ndarray  # (N,) s
    pressure_kpa: np.ndarray | None = None  # (N, K) kPa
    chamber_names: tuple[str, ...] = ()
    sample: np.ndarray | None = None  # (N,) int, -1: not a sample frame
    meta: dict = field(default_factory=dict)
    skipped_lines: int = 0
    _source: _NpyMember | np.ndarray | None = None  # the frames: a member or an (N, R, C) array
    pressure_t_s: np.ndarray | None = None  # (N,) s, host time of each frame's pressures
    printer_mm: np.ndarray | None = None  # (N, 3) mm, the bench printer's tip

    def __len__(self) -> int:
        return self.n_frames

    def read(self, start: int, count: int) -> np.ndarray:
        """Frames start .. start + count - 1 (clipped to the recording), checked, int64.
        Safe from several threads; the array may be overwritten by the same thread's
        next `read`: use it before reading on."""
        count = max(0, min(count, self.n_frames - start))
        if isinstance(self._source, np.ndarray):
            return self._source[start : start + count]
        assert self._source is not None, "a recording is opened with its frames"
        return check_frames(self._source.read(start, count), str(self.path), first=start)

    def chunks(self, size: int) -> Iterator[tuple[int, np.ndarray]]:
        """(first frame index, frames (n, R, C) int64) for consecutive chunks of `size`."""
        for start in range(0, self.n_frames, size):
            yield start, self.read(start, size)

    def verify(self) -> None:
        """With ``verify="read"``: FrameError unless the frames member's CRC-32 matches
        (after every frame was read); otherwise nothing to do."""
        if isinstance(self._source, _NpyMember):
            self._source.verify()

    def close(self) -> None:
        if isinstance(self._source, _NpyMember):
            self._source.close()

    def __enter__(self) -> ChunkedRecording:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _NpyMember:
    """The ``frames.npy`` member of an npz: header parsed, frames read on demand."""

    def __init__(
        self, path: Path, zf: zipfile.ZipFile, info: zipfile.ZipInfo, crc_on_read: bool = False
    ):
        self.path = path
        self._zip = zf
        self._info = info
        self._crc = None  # running CRC-32 of the member's bytes read in order, when checked
        self._fh: io.BufferedIOBase
        if info.compress_type == zipfile.ZIP_STORED:
            self._fh = open(path, "rb")
            self._fh.seek(info.header_offset)
            head = self._fh.read(_LOCAL_HEADER.size)
            if len(head) < _LOCAL_HEADER.size or head[:4] != _LOCAL_MAGIC:
                raise ValueError("bad zip entry")
            fields = _LOCAL_HEADER.unpack(head)
            begin = info.header_offset + _LOCAL_HEADER.size + fields[-2] + fields[-1]
            self._fh.seek(begin)
        else:
            member = zf.open(info)
            assert isinstance(member, zipfile.ZipExtFile)  # what ZipFile.open reads with
            self._fh = member
            begin = 0
        version = np.lib.format.read_magic(self._fh)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(self._fh)
        elif version == (2, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(self._fh)
        else:
            raise ValueError(f"npy format version {version}")
        if fortran or dtype.hasobject:
            raise ValueError("not a C-ordered array of plain numbers")
        self.shape, self.dtype = tuple(shape), dtype
        self.frame_bytes = int(np.prod(shape[1:], dtype=np.int64)) * dtype.itemsize
        self._data_at = self._fh.tell()
        n_frames = shape[0] if shape else 0
        if self._data_at - begin + n_frames * self.frame_bytes > info.file_size:
            raise ValueError(
                f"the member holds fewer bytes than its shape {tuple(shape)} needs (truncated)"
            )
        self._next = 0  # the frame the file is at
        if crc_on_read:
            if info.compress_type != zipfile.ZIP_STORED:  # zipfile checks it on reading
                _check_member(path, zf, info)
            else:
                self._fh.seek(begin)
                self._crc = zlib.crc32(self._fh.read(self._data_at - begin))
                self._crc_end = self._data_at - begin + n_frames * self.frame_bytes
                self._crc_upto = 0  # frame bytes in the running CRC
                self._crc_broken = self._crc_end != info.file_size
        self._lock = threading.Condition()  # one reader at a time: seek and read go together
        self._local = threading.local()  # each thread's read buffer, reused

    def read(self, start: int, count: int) -> np.ndarray:
        size = count * self.frame_bytes
        buf = getattr(self._local, "buf", None)
        if buf is None or buf.size < size:
            buf = self._local.buf = np.empty(size, np.uint8)
        view, got = buf[:size].data, 0  # a memoryview of the uint8 buffer
        lo = start * self.frame_bytes
        with self._lock:
            if self._crc is not None and not self._crc_broken and lo > self._crc_upto:
                # an earlier chunk's thread has not read yet: let it, for one running CRC
                self._lock.wait_for(lambda: lo <= self._crc_upto, timeout=0.5)
            if start != self._next:  # (zipfile seeks in a compressed member by reading on)
                self._fh.seek(self._data_at + start * self.frame_bytes)
            while got < size:
                try:
                    n = self._fh.readinto(view[got:])
                except (OSError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
                    self._next = -1
                    raise FrameError(
                        f"{self.path}: frames: cannot read frame "
                        f"{start + got // max(self.frame_bytes, 1)}: "
                        f"{exc}"
                    ) from None
                if not n:
                    self._next = -1
                    raise FrameError(
                        f"{self.path}: frames: the file ends inside frame "
                        f"{start + got // max(self.frame_bytes, 1)} (truncated)"
                    )
                got += n
            self._next = start + count
            if self._crc is not None and not self._crc_broken:
                if lo <= self._crc_upto < lo + size:
                    self._crc = zlib.crc32(view[self._crc_upto - lo :], self._crc)
                    self._crc_upto = lo + size
                    self._lock.notify_all()
                elif lo > self._crc_upto:
                    self._crc_broken = True  # a gap: verify reads the member again
                    self._lock.notify_all()
        return buf[:size].view(self.dtype).reshape((count, *self.shape[1:]))

    def verify(self) -> None:
        """Compare the running CRC-32 with the member's (see the module docstring)."""
        if self._crc is None:
            return
        with self._lock:
            whole = not self._crc_broken and self._crc_upto == self.shape[0] * self.frame_bytes
            crc, self._crc = self._crc, None
        if not whole:
            _check_member(self.path, self._zip, self._info)
        elif crc != self._info.CRC:
            raise FrameError(_crc_message(self.path, self._info.filename))

    def close(self) -> None:
        self._fh.close()
        self._zip.close()


def _crc_message(path: Path, member: str) -> str:
    return (
        f"{path}: not a readable .npz recording: member {member} fails its CRC check "
        "(the file is damaged)"
    )


def _check_member(path: Path, zf: zipfile.ZipFile, info: zipfile.ZipInfo) -> None:
    """Read one member whole: zipfile compares its CRC-32 at the end."""
    try:
        with zf.open(info) as fh:
            while fh.read(1 << 22):
                pass
    except zipfile.BadZipFile as exc:
        if "CRC" in str(exc):
            raise FrameError(_crc_message(path, info.filename)) from None
        raise FrameError(f"{path}: not a readable .npz recording: {exc}") from None
    except (OSError, EOFError, zlib.error, NotImplementedError) as exc:
        raise FrameError(f"{path}: not a readable .npz recording: {exc}") from None


def _open_npz(path: Path, verify: str = "open") -> ChunkedRecording:
    if not path.exists():
        raise FrameError(f"{path}: file not found")
    if verify == "open":
        check_zip(path, ".npz recording", FrameError)
    try:
        zf = zipfile.ZipFile(path)
    except (OSError, zipfile.BadZipFile) as exc:
        raise FrameError(f"{path}: not a readable .npz recording: {exc}") from None
    try:
        names = {n[:-4]: n for n in zf.namelist() if n.endswith(".npy")}
        if "frames" not in names:
            raise FrameError(f"{path}: missing key 'frames' (N, rows, cols) counts")
        if verify != "open":
            for info in zf.infolist():
                if info.filename != names["frames"]:
                    _check_member(path, zf, info)
        try:
            member = _NpyMember(path, zf, zf.getinfo(names["frames"]), verify != "open")
        except (
            ValueError,
            OSError,
            EOFError,
            NotImplementedError,
            zipfile.BadZipFile,
            zlib.error,
        ) as exc:
            raise FrameError(f"{path}: not a readable .npz recording: frames: {exc}") from None
    except BaseException:
        zf.close()
        raise
    try:
        shape = member.shape
        if len(shape) != 3:
            raise FrameError(f"{path}: frames: expected shape (N, rows, cols), got {shape}")
        if shape[0] == 0:
            raise FrameError(f"{path}: empty recording (no frames)")
        check_frames(np.zeros((1, *shape[1:]), member.dtype), str(path))  # the dtype
        try:
            with np.load(path, allow_pickle=False) as data:
                small = {k: data[k] for k in data.files if k != "frames"}
        except Exception as exc:
            why = (
                "it holds Python objects, not plain arrays"
                if "allow_pickle" in str(exc)
                else str(exc)
            )
            raise FrameError(f"{path}: not a readable .npz recording: {why}") from None
        t_s, pressure, chambers, sample, meta, pressure_t, printer = npz_extras(
            path, small, shape[0]
        )
    except BaseException:
        member.close()
        raise
    return ChunkedRecording(
        path,
        shape[0],
        (shape[1], shape[2]),
        t_s,
        pressure,
        chambers,
        sample,
        meta,
        0,
        member,
        pressure_t,
        printer,
    )


def in_memory(rec: Recording, path: str | os.PathLike = "frames") -> ChunkedRecording:
    """A recording already read whole, served in chunks."""
    frames = check_frames(rec.frames, str(path))
    return ChunkedRecording(
        Path(path),
        frames.shape[0],
        tuple(frames.shape[1:]),
        rec.t_s,
        rec.pressure_kpa,
        rec.chamber_names,
        rec.sample,
        rec.meta,
        rec.skipped_lines,
        frames,
        rec.pressure_t_s,
        rec.printer_mm,
    )


def has_pressures(path: str | os.PathLike, board: BoardSection) -> bool:
    """Whether the recording at `path` carries chamber pressures (`board`: the scene's
    [board]; an .npz is read from its header only, a MuCa log whole, so the answer is
    kept per file version: the planner asks several times for one run)."""
    st = os.stat(path)
    return _has_pressures(
        str(Path(path).resolve()), st.st_size, st.st_mtime_ns, board.rows, board.cols, board.format
    )


@functools.lru_cache(maxsize=16)
def _has_pressures(path: str, size: int, mtime_ns: int, rows: int, cols: int, fmt: str) -> bool:
    with open_recording(path, rows, cols, fmt) as rec:
        return rec.pressure_kpa is not None


def open_recording(
    path: str | os.PathLike,
    rows: int = BOARD_ROWS,
    cols: int = BOARD_COLS,
    fmt: str = "auto",
    verify: str = "open",
) -> ChunkedRecording:
    """An `.npz` (frames read chunk by chunk), or a MuCa ASCII log or raw board capture
    (read whole, `fmt` as `read_recording` takes it), by suffix as `read_recording` does.
    Use it as a context manager (it holds the file open). An `.npz`'s CRCs are checked
    on opening (`verify` "open"), or the frames' as they are read ("read": the caller
    must call `ChunkedRecording.verify` after reading every frame)."""
    path = Path(path)
    if verify not in ("open", "read"):
        raise ValueError(f"verify: expected open or read, got {verify!r}")
    if path.suffix.lower() == ".npz":
        return _open_npz(path, verify)
    return in_memory(read_recording(path, rows, cols, fmt), path)
