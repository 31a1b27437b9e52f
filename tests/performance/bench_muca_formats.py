"""Decoding the stock MuCa firmware's formats: frames/s of the ASCII and binary decoders
in steady state, the cost of one binary resynchronization, and what the serial line
allows (115200 baud 8N1)."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from fruitcli.sensing.frames.muca import decode_bytes, format_ascii_line
from fruitcli.sensing.live.board_emulator import pacing_line
from tests.sensing.frames.test_muca import START, binary_stream, board_frames


def timed(data: bytes, fmt: str, repeats: int = 3) -> tuple[float, int]:
    best, n = np.inf, 0
    for _ in range(repeats):
        t0 = time.perf_counter()
        frames, _ = decode_bytes(data, fmt, 21, 12)
        best = min(best, time.perf_counter() - t0)
        n = len(frames)
    return best, n


def main() -> None:
    frames = board_frames(2000, seed=1)
    ascii_bytes = START + b"".join(format_ascii_line(f) for f in frames)
    for name, data, fmt in (
        ("ASCII", ascii_bytes, "ascii"),
        ("binary", binary_stream(frames), "binary"),
        ("binary, auto-detected", binary_stream(frames), "auto"),
    ):
        dt, n = timed(data, fmt)
        print(f"{name:24s} {n} frames in {dt * 1e3:7.1f} ms: {n / dt:9.0f} frames/s")
    damage = {k: ("lose", 100) for k in range(20, 2000, 20)}
    dt_clean, _ = timed(binary_stream(frames), "binary")
    dt_dmg, n = timed(binary_stream(frames, damage), "binary")
    print(
        f"binary, a lost byte every 20 frames: {n} of 2000 frames kept "
        f"({2000 - n} lost for {len(damage)} lost bytes), "
        f"{(dt_dmg - dt_clean) / len(damage) * 1e3:.1f} ms per resynchronization"
    )
    for fmt in ("ascii", "binary"):
        print(f"{fmt:6s} at {pacing_line(fmt, 115200, frames=frames)}")


if __name__ == "__main__":
    main()
