"""Sensing speed: detection + 3D location in batch (replay) and per frame (live loop).

Targets (issue 5): >= 100,000 frames/s in batch on 21 x 12 frames; <= 0.1 ms median per
frame in the live loop. 47 taxels on a 12 x 7 taxel grid, half the frames touched
(one or two touches), taxels moving through 5 FEM states by chamber pressure.
"""

from __future__ import annotations

import time

import numpy as np

from fruitcli.sensing.board import Taxels, default_board
from fruitcli.sensing.frames_io import format_line, parse_line
from fruitcli.sensing.pipeline import Locator, Settings, Stream


def fruit_like_taxels() -> Taxels:
    i, j = np.meshgrid(np.arange(12), np.arange(7), indexing="ij")
    i, j = i.ravel(), j.ravel()
    keep = np.hypot((i - 5.5) / 6.5, (j - 3) / 4.2) <= 1.0  # an oval patch
    i, j = i[keep][:47], j[keep][:47]
    xyz = np.stack([16.0 * i, 12.0 * j, 5 * np.sin(i / 3)], axis=1)
    return Taxels(np.arange(len(i)), i, j, xyz)


def frames_with_touches(n: int, taxels: Taxels, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    f = 500 + rng.normal(0, 1.5, (n, 21, 12))
    r, c = np.meshgrid(np.arange(21), np.arange(12), indexing="ij")
    for k in range(2):
        touched = rng.random(n) < (0.5 if k == 0 else 0.15)
        centre = taxels.i[rng.integers(len(taxels), size=n)], taxels.j[rng.integers(
            len(taxels), size=n)]
        blob = 60 * np.exp(-((r - centre[0][:, None, None] - 0.3) ** 2
                             + (c - centre[1][:, None, None] + 0.25) ** 2) / 1.2)
        f += blob * touched[:, None, None]
    return np.maximum(np.round(f), 0).astype(np.int64)


def main():
    taxels = fruit_like_taxels()
    states = np.stack([taxels.xyz_mm + [0, 0, 2.0 * s] for s in range(5)])
    state_kpa = np.stack([np.linspace(0, 8, 5), np.linspace(0, 4, 5)], axis=1)
    settings = Settings(baseline_frames=10)
    loc = Locator(taxels, default_board(), states, settings, state_kpa)
    n = 200_000
    frames = frames_with_touches(n, taxels)
    kpa = np.random.default_rng(1).uniform(0, 8, (n, 2))
    base = loc.baseline(frames)
    loc.batch(frames[:1000], base, kpa[:1000])  # warm up
    t0 = time.perf_counter()
    table = loc.batch(frames, base, kpa)
    dt = time.perf_counter() - t0
    print(f"batch: {n} frames of 21x12, {len(table)} touches, {dt:.3f} s -> "
          f"{n / dt:,.0f} frames/s (target >= 100,000)")
    rest = Locator(taxels, default_board(), taxels.xyz_mm, settings)
    t0 = time.perf_counter()
    rest.batch(frames, base)
    dt = time.perf_counter() - t0
    print(f"batch at rest (no pressure interpolation): {n / dt:,.0f} frames/s")

    stream = Stream(loc, base)
    values = loc.values(frames[:20_000])
    times = np.empty(len(values))
    for k, v in enumerate(values):
        t = time.perf_counter()
        stream.step(v, kpa[k], k)
        times[k] = time.perf_counter() - t
    print(f"live loop (detect + locate per frame): median {np.median(times) * 1e3:.4f} ms, "
          f"p99 {np.percentile(times, 99) * 1e3:.4f} ms (target median <= 0.1 ms)")
    lines = [format_line(f) for f in frames[:5000]]
    t0 = time.perf_counter()
    for line in lines:
        parse_line(line, 252)
    dt = (time.perf_counter() - t0) / len(lines)
    print(f"live loop line parsing (252 counts): {dt * 1e3:.4f} ms per frame")


def bench_osc_latency(n_frames: int = 3000):
    """Issue 15: board line arriving -> last TUIO/OSC bundle of the frame leaving, with 10
    simultaneous touches (target p99 <= 1 ms). Each frame's line is written to a pty; the
    clock starts when the pty has it for the reader (select), then the live loop's own
    objects read, parse, locate, give session ids and send 4 bundles to 127.0.0.1, in
    one thread."""
    import os
    import select
    import socket
    import tty

    from fruitcli.sensing.live import LiveLocator
    from fruitcli.sensing.serial_io import FrameReader, open_port
    from fruitcli.sensing.tuio import Normalizer, TuioSender

    i, j = np.divmod(np.arange(21 * 12), 12)
    taxels = Taxels(np.arange(i.size), i, j, np.stack([16.0 * i, 12.0 * j, 0 * i], axis=1))
    loc = Locator(taxels, default_board(), taxels.xyz_mm, Settings(baseline_frames=10))
    live = LiveLocator(loc)
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    sink.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    tuio = TuioSender(sink.getsockname(), Normalizer.from_taxels(i, j, taxels.xyz_mm))
    master, slave = os.openpty()
    tty.setraw(slave)
    port = open_port(os.ttyname(slave))
    reader = FrameReader(port, 21, 12, "pty")
    rng = np.random.default_rng(7)
    r, c = np.meshgrid(np.arange(21), np.arange(12), indexing="ij")
    centres = [(a, b) for a in (2, 7, 12, 17) for b in (2, 6, 10)][:10]
    lat, cpu, counts = [], [], []
    try:
        for k in range(n_frames + 10):
            f = 500 + rng.normal(0, 1.0, (21, 12))
            if k >= 10:
                for a, b in centres:
                    d = 0.3 * np.sin(k / 20)  # the fingers move a little
                    f += 60 * np.exp(-((r - a - d) ** 2 + (c - b + d) ** 2) / (2 * 0.6 ** 2))
            line = (format_line(np.round(f).astype(np.int64)) + "\r\n").encode()
            while os.read(sink.fileno(), 65536) if _readable(sink) else False:
                pass  # drain what the previous frames sent
            os.write(master, line)
            select.select([port.fileno()], [], [])
            t0, c0 = time.perf_counter(), time.thread_time()
            got = []
            while not got:
                got = reader.poll()
            lf = live.step(got[0][0], got[0][1])
            if lf is not None:
                tuio.send(lf.t_s, lf.sessions.ids, lf.sessions.new, lf.sessions.ended,
                          lf.ij, lf.touches.xyz_mm, lf.touches.peak)
                lat.append(time.perf_counter() - t0)
                cpu.append(time.thread_time() - c0)
                counts.append(len(lf.touches))
    finally:
        port.close()
        os.close(master)
        os.close(slave)
        sink.close()
        tuio.close()
    ms = np.array(lat) * 1e3
    print(f"OSC latency, board line -> TUIO bundles sent, {int(np.median(counts))} touches "
          f"({min(counts)}-{max(counts)}), {len(ms)} frames: median {np.median(ms):.3f} ms, "
          f"p99 {np.percentile(ms, 99):.3f} ms, max {ms.max():.3f} ms (target p99 <= 1 ms); "
          f"CPU time of the loop's thread: median {np.median(cpu) * 1e3:.3f} ms, p99 "
          f"{np.percentile(cpu, 99) * 1e3:.3f} ms (wall minus CPU: waiting for a core)")


def _readable(sock) -> bool:
    """Data waiting on `sock`."""
    import select

    return bool(select.select([sock], [], [], 0)[0])


if __name__ == "__main__":
    main()
    bench_osc_latency()
