"""An exhibition day on an emulated board, in compressed time: thermal baseline drift,
noise, visitors' touches and cable pulls (the soak test of `fruit live --reconnect`).

Units: counts, s of emulated time, frames/s. The board is reached through a stable
path (a symlink, as udev's /dev/serial/by-id names are) to the pty of the current
connection: a pull closes the pty in the middle of a line and removes the link; after
the pull's duration a new pty appears behind the same path. Frames are played at
`fps` emulated frames per second, `time_scale` times faster than real time.
"""

from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fruitcli.sensing.live.board_emulator import BoardEmulator


@dataclass(frozen=True)
class Touch:
    """A visitor's touch: start and end (emulated s), frame cell (row, col), counts."""

    start_s: float
    end_s: float
    row: float
    col: float
    counts: float


@dataclass
class SoakPlan:
    """What happens over the run (emulated time). Touches keep `quiet_after_s` away from
    the start and from every replug: the board's new baseline needs untouched frames."""

    hours: float = 8.0
    fps: float = 1.0
    drift_counts: float = 40.0  # the largest taxel's thermal drift over the run
    noise_std: float = 1.0
    touch_every_s: float = 6.0
    touch_s: float = 2.0
    touch_counts: float = 60.0
    touch_sigma_cells: float = 0.8
    pulls: tuple[tuple[float, float], ...] = (
        (5 * 3600.0, 60.0),
        (6.5 * 3600.0, 30.0),
        (7.5 * 3600.0, 120.0),
    )  # (start, length) s
    quiet_after_s: float = 20.0
    rows: int = 21
    cols: int = 12
    cells: tuple[tuple[int, int], ...] = ()  # where touches land (default: inner cells)
    seed: int = 0
    touches: list[Touch] = field(default_factory=list)

    def __post_init__(self):
        rng = np.random.default_rng(self.seed)
        cells = self.cells or tuple(
            (r, c) for r in range(1, self.rows - 1) for c in range(1, self.cols - 1)
        )
        self.base = 500 + rng.normal(0, 30, (self.rows, self.cols))
        self.drift_share = rng.uniform(0.5, 1.0, (self.rows, self.cols))
        self.drift_share /= self.drift_share.max()  # the largest drifts drift_counts
        self._rng = np.random.default_rng(self.seed + 1)
        quiet = [(0.0, self.quiet_after_s)] + [
            (a, a + d + self.quiet_after_s) for a, d in self.pulls
        ]
        t = self.quiet_after_s
        end = self.hours * 3600.0
        while t + self.touch_s < end:
            t0, t1 = t, t + self.touch_s
            if not any(t0 < b and t1 > a for a, b in quiet):
                r, c = cells[int(rng.integers(len(cells)))]
                jr, jc = rng.uniform(-0.3, 0.3, 2)
                self.touches.append(Touch(t0, t1, r + jr, c + jc, self.touch_counts))
            t += self.touch_every_s

    def connected(self) -> list[tuple[float, float]]:
        """(start, end) emulated s of each connection."""
        out, t = [], 0.0
        for a, d in self.pulls:
            out.append((t, a))
            t = a + d
        out.append((t, self.hours * 3600.0))
        return out

    def frames(self, t0: float, t1: float) -> np.ndarray:
        """Frames (N, R, C) counts at emulated times k / fps in [t0, t1)."""
        times = np.arange(np.ceil(t0 * self.fps), np.ceil(t1 * self.fps)) / self.fps
        drift = self.drift_counts * times / (self.hours * 3600.0)
        f = self.base + drift[:, None, None] * self.drift_share
        f = f + self._rng.normal(0, self.noise_std, f.shape)
        r, c = np.meshgrid(np.arange(self.rows), np.arange(self.cols), indexing="ij")
        for tc in self.touches:
            on = (times >= tc.start_s) & (times < tc.end_s)
            if on.any():
                blob = tc.counts * np.exp(
                    -((r - tc.row) ** 2 + (c - tc.col) ** 2) / (2 * self.touch_sigma_cells**2)
                )
                f[on] += blob
        return np.maximum(np.round(f), 0).astype(np.int32)

    def frame_times(self, t0: float, t1: float) -> np.ndarray:
        return np.arange(np.ceil(t0 * self.fps), np.ceil(t1 * self.fps)) / self.fps


class SoakBoard:
    """Play a `SoakPlan` behind the stable path `link` in a thread (`start`)."""

    def __init__(self, plan: SoakPlan, link: str | os.PathLike, time_scale: float):
        self.plan, self.link, self.scale = plan, Path(link), time_scale
        self.sent: list[int] = []  # whole frames sent per connection
        self.stop = threading.Event()
        self.done = threading.Event()
        self.error: BaseException | None = None

    def _connect(self, frames: np.ndarray, last: bool) -> int:
        n = len(frames)
        if not last:  # one more frame, cut in the middle of its line by the pull
            frames = np.concatenate([frames, frames[-1:]])
        em = BoardEmulator(
            frames,
            self.plan.fps,
            wait_for_reader=True,
            time_scale=self.scale,
            vanish_after=None if last else n,
        )
        tmp = self.link.with_name(self.link.name + ".new")
        tmp.unlink(missing_ok=True)
        os.symlink(em.path, tmp)
        os.replace(tmp, self.link)  # the port appears at once, complete
        if last:
            return em.play()
        # a pull: play() sends the frames, then half a line; the link goes first
        th = threading.Thread(target=em.play, daemon=True)
        th.start()
        while th.is_alive() and em.sent < n and not self.stop.is_set():
            time.sleep(0.005)
        self.link.unlink(missing_ok=True)
        th.join()
        return em.sent

    def run(self) -> None:
        try:
            spans = self.plan.connected()
            for k, (t0, t1) in enumerate(spans):
                if self.stop.is_set():
                    break
                last = k == len(spans) - 1
                self.sent.append(self._connect(self.plan.frames(t0, t1), last))
                if not last:  # unplugged for the pull's length
                    time.sleep(self.plan.pulls[k][1] / self.scale)
            self.link.unlink(missing_ok=True)
        except BaseException as exc:  # reported by the test
            self.error = exc
        finally:
            self.done.set()

    def start(self) -> threading.Thread:
        th = threading.Thread(target=self.run, daemon=True)
        th.start()
        return th
