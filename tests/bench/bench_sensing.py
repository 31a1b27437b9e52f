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


if __name__ == "__main__":
    main()
