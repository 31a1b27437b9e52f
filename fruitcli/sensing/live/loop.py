"""The live loop: baseline from the first K frames, then touches of every frame in 3D.

Units: counts, mm, kPa, s. Output: one JSON object per frame that has touches, and one
with ``"touches": []`` on the frame where the last touch ends:
``{"frame": n, "t_s": t, "touches": [{"touch", "i", "j", "x_mm", "y_mm", "z_mm",
"peak", "height_mm", "height_err_mm", "strength", "size_mm", "kind"}]}`` (frame counts
from 0 including the baseline frames; ``touch`` is the session id: a finger keeps it
across frames, also from hovering to touching; ids are never reused, see `sessions`;
kind "touch" or "hover"; a size not measured is null).

Optional per-run state: a `DriftTracker` (the baseline follows slow drift on quiet
frames) and `TaxelHealth` flags. `rebaseline()` (after the board reconnected) collects K
new baseline frames and ends every touch.
"""

from __future__ import annotations

import json
import threading
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Protocol

import numpy as np

from fruitcli.sensing.detection.drift import DriftTracker
from fruitcli.sensing.detection.frames_to_touches import Locator, Stream
from fruitcli.sensing.detection.health import TaxelHealth
from fruitcli.sensing.detection.model_fit import FIT_NAMES, FIT_NONE
from fruitcli.sensing.detection.sessions import DEFAULT_GATE_MM, SessionStep, SessionTracker
from fruitcli.sensing.detection.touch_table import KIND_NAMES, TouchTable
from fruitcli.sensing.live.serial_ports import LineReader, PortClosed, PressureState

if TYPE_CHECKING:
    from serial import SerialBase


BROKEN_EVERY = 30  # frames between refreshes of the taxel flags the drift tracker ignores


class OnlinePositions(Protocol):
    """What the live loop reads of an online solver (`fruitcli.fem.online.OnlineSolver`):
    the taxel positions (T, 3) mm at the last solved pressures."""

    @property
    def taxels_mm(self) -> np.ndarray: ...


@dataclass
class LiveFrame:
    """One located frame: its touches with session ids, and the taxels' state."""

    frame: int
    t_s: float
    touches: TouchTable  # touch = session id
    sessions: SessionStep
    values: np.ndarray  # (T,) raw counts
    activation: np.ndarray  # (T,) v = C - C0 clipped at 0 (counts)

    @property
    def ij(self) -> np.ndarray:
        return np.column_stack([self.touches.i, self.touches.j])

    @property
    def shape(self) -> np.ndarray:
        """(n, 3) height mm, strength, size mm of the touches."""
        t = self.touches
        return np.column_stack([t.height_mm, t.strength, t.size_mm])


class LiveLocator:
    """Feed frames one by one; `step` returns a `LiveFrame` (None while collecting the
    baseline), `push` its JSON line or None. With `online` (an object whose `taxels_mm`
    (T, 3) holds the taxels at the latest measured pressures,
    `fruitcli.fem.online.OnlineSolver`), each frame uses those positions."""

    def __init__(
        self,
        locator: Locator,
        pressure: PressureState | None = None,
        online: OnlinePositions | None = None,
        gate_mm: float = DEFAULT_GATE_MM,
        drift: DriftTracker | None = None,
        health: bool = False,
    ):
        if drift is not None and locator.settings.drift_rate > 0:
            # one tracker: the per-frame rate of the bench replays gives way to this one
            locator.settings = replace(locator.settings, drift_rate=0.0)
        self.loc = locator
        self._cells = locator.rows * locator.frame_shape[1] + locator.cols  # flat frame
        self.pressure = pressure
        self.online = online
        self.k = locator.settings.baseline_frames
        self.sessions = SessionTracker(gate_mm)
        self.drift = drift
        self.health = (
            TaxelHealth(len(locator.rows), locator.settings.threshold_counts) if health else None
        )
        self._base: list[np.ndarray] = []
        self.stream: Stream | None = None
        self.initial_baseline: np.ndarray | None = None
        self.frame = -1
        self.baselines = 0  # baselines taken (1 + re-baselines)
        self._had = False
        self._broken: np.ndarray | None = None  # taxels flagged by `health`, every BROKEN_EVERY

    @property
    def baseline_state(self) -> str:
        """'collecting k/K' or 'tracking' / 'fixed' (with a drift tracker or without)."""
        if self.stream is None:
            return f"collecting {len(self._base)}/{self.k}"
        return "tracking" if self.drift is not None else "fixed"

    def rebaseline(self, t_s: float) -> tuple[list[int], str | None]:
        """Start a new baseline (the board was away); -> the sessions that ended and the
        JSON line saying so (``"touches": []``; None when no touch was going on)."""
        self._base, self.stream = [], None
        if self.drift is not None:
            self.drift.reset()
        line = (
            json.dumps({"frame": self.frame, "t_s": round(float(t_s), 6), "touches": []})
            if self._had
            else None
        )
        self._had = False
        return self.sessions.end_all(), line

    def step(self, counts: np.ndarray, t_s: float) -> LiveFrame | None:
        """One frame (R, C) counts at host time `t_s` (s)."""
        self.frame += 1
        values = counts.take(self._cells).astype(float)
        if self.stream is None:
            self._base.append(values)
            if len(self._base) == self.k:
                self.stream = Stream(self.loc, np.mean(self._base, axis=0))
                self.baselines += 1
                if self.initial_baseline is None:
                    self.initial_baseline = self.stream.baseline.copy()
            return None
        p = None if self.pressure is None else self.pressure.kpa
        if self.online is not None:
            self.loc.positions_mm, p = self.online.taxels_mm, None
        base = self.stream.baseline
        t = self.stream.step(values, p, self.frame)
        activation = self.stream.activation  # v = C - C0 clipped, before any gain division
        s = self.sessions.update(t.xyz_mm)
        t.touch = s.ids
        if self.health is not None:
            self.health.update(values, quiet=len(t) == 0)
            if self.frame % BROKEN_EVERY == 0:
                self._broken = self.health.broken()
        if self.drift is not None:
            self.drift.update(base, values, t_s, self._broken)
        return LiveFrame(self.frame, t_s, t, s, values, activation)

    def push(self, counts: np.ndarray, t_s: float) -> str | None:
        """`step`, as a JSON line (None when there is nothing to say)."""
        f = self.step(counts, t_s)
        return None if f is None else self.json_line(f)

    def json_line(self, f: LiveFrame) -> str | None:
        """The frame's JSON line: touches, or [] on the frame the last one ended."""
        t = f.touches
        if len(t) == 0 and not self._had:
            return None
        self._had = len(t) > 0
        touches = [
            {
                "touch": int(t.touch[n]),
                "i": round(float(t.i[n]), 4),
                "j": round(float(t.j[n]), 4),
                **{
                    k: round(float(v), 4)
                    for k, v in zip(("x_mm", "y_mm", "z_mm"), t.xyz_mm[n], strict=True)
                },
                "peak": float(t.peak[n]),
                **_shape(t, n),
            }
            for n in range(len(t))
        ]
        return json.dumps({"frame": f.frame, "t_s": round(float(f.t_s), 6), "touches": touches})

    def baseline_shift(self) -> np.ndarray:
        """(T,) counts the baseline moved since the first one (0 before it)."""
        if self.stream is None or self.initial_baseline is None:
            return np.zeros(len(self.loc.rows))
        return self.stream.baseline - self.initial_baseline


def _shape(t: TouchTable, n: int) -> dict:
    """Height, strength, size and kind of touch n, for its JSON line (NaN: null)."""
    out: dict[str, float | str | None] = {
        k: (None if np.isnan(v) else round(float(v), 4))
        for k, v in (
            ("height_mm", t.height_mm[n]),
            ("height_err_mm", t.height_err_mm[n]),
            ("strength", t.strength[n]),
            ("size_mm", t.size_mm[n]),
        )
    }
    out["kind"] = KIND_NAMES[int(t.kind[n])]
    if t.fit[n] != FIT_NONE:  # the model method's fit
        for k, v in (("pos_err_mm", t.pos_err_mm[n]), ("residual", t.residual[n])):
            out[k] = None if np.isnan(v) else round(float(v), 4)
        out["fit"] = FIT_NAMES[int(t.fit[n])]
    return out


def pressure_thread(
    port: SerialBase, state: PressureState, stop: threading.Event, name: str = "pressure port"
) -> threading.Thread:
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
