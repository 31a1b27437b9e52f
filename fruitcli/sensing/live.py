"""The live loop: baseline from the first K frames, then touches of every frame in 3D.

Units: counts, mm, kPa, s. Output: one JSON object per frame that has touches, and one
with ``"touches": []`` on the frame where the last touch ends:
``{"frame": n, "t_s": t, "touches": [{"touch", "i", "j", "x_mm", "y_mm", "z_mm",
"peak"}]}`` (frame counts from 0 including the baseline frames).
"""

from __future__ import annotations

import json
import threading

import numpy as np

from fruitcli.sensing.pipeline import Locator, Stream
from fruitcli.sensing.serial_io import LineReader, PortClosed, PressureState


class LiveLocator:
    """Feed frames one by one; `push` returns a JSON line or None. With `online` (an
    object whose `taxels_mm` (T, 3) holds the taxels at the latest measured pressures,
    `fruitcli.fem.online.OnlineSolver`), each frame uses those positions."""

    def __init__(self, locator: Locator, pressure: PressureState | None = None,
                 online=None):
        self.loc = locator
        self.pressure = pressure
        self.online = online
        self.k = locator.settings.baseline_frames
        self._base: list[np.ndarray] = []
        self.stream: Stream | None = None
        self.frame = -1
        self._had = False

    def push(self, counts: np.ndarray, t_s: float) -> str | None:
        """One frame (R, C) counts at host time `t_s`."""
        self.frame += 1
        values = counts[self.loc.rows, self.loc.cols].astype(float)
        if self.stream is None:
            self._base.append(values)
            if len(self._base) == self.k:
                self.stream = Stream(self.loc, np.mean(self._base, axis=0))
            return None
        p = None if self.pressure is None else self.pressure.kpa
        if self.online is not None:
            self.loc.positions_mm, p = self.online.taxels_mm, None
        t = self.stream.step(values, p, self.frame)
        if len(t) == 0 and not self._had:
            return None
        self._had = len(t) > 0
        touches = [{"touch": int(t.touch[n]), "i": round(float(t.i[n]), 4),
                    "j": round(float(t.j[n]), 4),
                    **{k: round(float(v), 4) for k, v in zip(("x_mm", "y_mm", "z_mm"),
                                                            t.xyz_mm[n], strict=True)},
                    "peak": float(t.peak[n])} for n in range(len(t))]
        return json.dumps({"frame": self.frame, "t_s": round(float(t_s), 6),
                           "touches": touches})


def pressure_thread(port, state: PressureState, stop: threading.Event,
                    name: str = "pressure port") -> threading.Thread:
    """Read pressure lines from `port` into `state` until `stop` or the port closes."""
    reader = LineReader(port, name)

    def run():
        while not stop.is_set():
            try:
                lines = reader.poll()
            except PortClosed:
                state.closed = True  # said in the closing summary
                return
            for line in lines:
                state.update(line)

    th = threading.Thread(target=run, daemon=True)
    th.start()
    return th
