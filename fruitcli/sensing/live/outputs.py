"""Where each frame of `fruit live` goes: JSON lines on stdout, TUIO/OSC, the run log and
the live view; and the run's counters (reconnects, frames per second, status lines).

Units: s (host time of the run, scaled by ``--time-scale``), mm, counts.
"""

from __future__ import annotations

import sys
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np

from fruitcli.sensing.detection.touch_table import KIND_NAMES
from fruitcli.sensing.live.run_log import STATUS_EVERY_S

if TYPE_CHECKING:
    from serial import SerialBase

    from fruitcli.sensing.live.loop import LiveFrame, LiveLocator
    from fruitcli.sensing.live.run_log import RunLog
    from fruitcli.sensing.live.serial_ports import FrameReader, PressureState
    from fruitcli.sensing.outputs.live_view import ViewServer
    from fruitcli.sensing.outputs.tuio import TuioSender
    from fruitcli.tables import Taxels


def _finite(x: float) -> float | None:
    """x as a float, None when NaN (JSON has no NaN)."""
    return None if np.isnan(x) else float(x)


class BoardShape(Protocol):
    """What a reconnect reads of the scene's ``[board]``: its frame's rows and columns."""

    @property
    def rows(self) -> int: ...
    @property
    def cols(self) -> int: ...


class Outputs:
    """Where each located frame goes: stdout (JSON lines), TUIO/OSC, the run log; and
    the run's counters (reconnects, frames per second, status)."""

    def __init__(
        self,
        live_loc: LiveLocator,
        taxels: Taxels,
        progress: Callable[[str], None],
        time_scale: float = 1.0,
        pressure: PressureState | None = None,
    ):
        self.live, self.taxels, self.progress = live_loc, taxels, progress
        self.pressure = pressure
        self.view: ViewServer | None = None
        self.last: LiveFrame | None = None  # the latest frame (for the view)
        self.recent: deque[float] = deque(maxlen=32)  # host times of the latest frames (frames/s)
        self.scale = time_scale
        self.t0 = time.monotonic()
        self.tuio: TuioSender | None = None
        self.log: RunLog | None = None
        self.reconnects = 0
        self.skipped = 0  # lines skipped by earlier connections' readers
        self.frames = 0
        self.touches = 0  # sessions that touched (hovers alone are not counted)
        self._touching: set[int] = set()  # alive sessions already counted
        self.next_status = STATUS_EVERY_S
        self._status_frames, self._status_t = 0, 0.0

    def now(self, monotonic_s: float) -> float:
        """Host time of the run (s), scaled by --time-scale."""
        return (monotonic_s - self.t0) * self.scale

    def frame(self, counts: np.ndarray, monotonic_s: float) -> None:
        t = self.now(monotonic_s)
        f = self.live.step(counts, t)
        self.frames += 1
        self.recent.append(t)
        self.last = f
        if f is not None:
            tt = f.touches
            if self.tuio is not None:  # first: a slow reader of stdout must not delay it
                self.tuio.send(
                    t,
                    f.sessions.ids,
                    f.sessions.new,
                    f.sessions.ended,
                    f.ij,
                    tt.xyz_mm,
                    tt.peak,
                    f.shape,
                    tt.kind,
                )
            line = self.live.json_line(f)
            if line is not None:
                sys.stdout.write(line + "\n")
                sys.stdout.flush()
            self._count_touches(f)
            if self.log is not None:
                self.log.frame(t, f.sessions, tt.xyz_mm, f.ij, tt.peak)
        if self.log is not None and t >= self.next_status:
            self.log.status(self.status(t))
            self.next_status = t + STATUS_EVERY_S

    def _count_touches(self, f: LiveFrame) -> None:
        """Count each session once, on its first frame of kind touch."""
        ids = f.sessions.ids.tolist()
        touched = {s for s, k in zip(ids, f.touches.kind.tolist(), strict=True) if k == 0}
        self.touches += len(touched - self._touching)
        self._touching = (self._touching | touched) & set(ids)

    def fps(self, t: float) -> float:
        n, dt = self.frames - self._status_frames, t - self._status_t
        self._status_frames, self._status_t = self.frames, t
        return n / dt if dt > 0 else 0.0

    def status(self, t: float) -> str:
        shift = self.live.baseline_shift()
        h = self.live.health
        return (
            f"t {t:.0f} s, {self.frames} frames, {self.fps(t):.1f} frames/s, "
            f"{self.touches} touches, baseline {self.live.baseline_state} (shift mean "
            f"{float(np.mean(shift)):+.1f}, max |{float(np.abs(shift).max()):.1f}| "
            f"counts), {self.reconnects} reconnects, "
            + (h.summary(self.taxels.ids) if h is not None else "")
        )

    def reconnect(
        self,
        port: str,
        baud: int,
        board: BoardShape,
        fmt: str,
        wait_for_port: Callable[[str, int], SerialBase],
    ) -> tuple[SerialBase, FrameReader]:
        """The port vanished: end the touches, wait for the port, start a new baseline."""
        from fruitcli.sensing.live.serial_ports import FrameReader

        t = self.now(time.monotonic())
        ended, line = self.live.rebaseline(t)
        self.last = None
        if line is not None:
            sys.stdout.write(line + "\n")
            sys.stdout.flush()
        self._ended(t, ended)
        self.progress(f"{port}: port lost after {self.frames} frames; waiting for it")
        if self.log is not None:
            self.log.event(f"port {port} lost at t {t:.1f} s")
        ser = wait_for_port(port, baud)
        self.reconnects += 1
        self.progress(
            f"{port}: reconnected ({self.reconnects}); collecting {self.live.k} baseline frames"
        )
        if self.log is not None:
            self.log.event(
                f"port {port} back at t {self.now(time.monotonic()):.1f} s, "
                f"reconnect {self.reconnects}"
            )
        return ser, FrameReader(ser, board.rows, board.cols, name=port, fmt=fmt)

    def start_view(self, target: str) -> None:
        from fruitcli.sensing.outputs.live_view import ViewServer
        from fruitcli.sensing.outputs.tuio import parse_host_port

        host, port = parse_host_port(target, "--view", default_host="127.0.0.1")
        tx = self.taxels
        layout = {
            "taxels": [
                [
                    int(tx.ids[k]),
                    int(tx.i[k]),
                    int(tx.j[k]),
                    float(tx.xyz_mm[k, 0]),
                    float(tx.xyz_mm[k, 1]),
                ]
                for k in range(len(tx))
            ],
            "threshold_counts": self.live.loc.settings.threshold_counts,
        }
        self.view = view = ViewServer(host, port, layout, self.view_state)
        self.progress(f"live view at {view.url}")

    def view_state(self) -> dict:
        """The live view's state (called from the view's threads)."""
        f, recent = self.last, list(self.recent)
        fps = (
            (len(recent) - 1) / (recent[-1] - recent[0])
            if len(recent) > 1 and recent[-1] > recent[0]
            else 0.0
        )
        touches: list[dict[str, object]] = []
        if f is not None:
            tt = f.touches
            touches = [
                {
                    "id": int(tt.touch[n]),
                    "x_mm": float(tt.xyz_mm[n, 0]),
                    "y_mm": float(tt.xyz_mm[n, 1]),
                    "z_mm": float(tt.xyz_mm[n, 2]),
                    "i": float(tt.i[n]),
                    "j": float(tt.j[n]),
                    "peak": float(tt.peak[n]),
                    "kind": KIND_NAMES[int(tt.kind[n])],
                    "height_mm": _finite(tt.height_mm[n]),
                }
                for n in range(len(tt))
            ]
        act = f.activation if f is not None else [0.0] * len(self.taxels)
        h = self.live.health
        flags = (
            {name: self.taxels.ids[idx].tolist() for name, idx in h.flags().items()}
            if h is not None
            else {}
        )
        p = self.pressure
        return {
            "frame": self.live.frame,
            "t_s": round(self.now_s(), 3),
            "fps": fps,
            "baseline": self.live.baseline_state,
            "reconnects": self.reconnects,
            "activation": [round(float(v), 1) for v in act],
            "touches": touches,
            "pressures": {}
            if p is None or not p.received
            else dict(zip(p.chambers, (float(v) for v in p.kpa), strict=True)),
            "flags": flags,
        }

    def now_s(self) -> float:
        return self.now(time.monotonic())

    def _ended(self, t: float, ended: list[int]) -> None:
        """Touches that ended without a frame (the board went away)."""
        e = np.zeros(0)
        if self.tuio is not None:
            self.tuio.send(
                t, e.astype(np.int64), e.astype(bool), ended, np.zeros((0, 2)), np.zeros((0, 3)), e
            )
        if self.log is not None:
            self.log.ended(t, ended)

    def summary(self) -> list[str]:
        lines = []
        if self.reconnects:
            lines.append(
                f"{self.reconnects} reconnect{'s' * (self.reconnects != 1)} "
                f"({self.skipped} lines skipped before the last one)"
            )
        if self.live.drift is not None:
            lines.append(self.live.drift.state())
        if self.live.health is not None:
            lines.append(self.live.health.summary(self.taxels.ids))
        if self.tuio is not None:
            lines.append(f"OSC: {self.tuio.sent} bundles sent, {self.tuio.failed} failed")
        if self.log is not None and self.log.failed:
            lines.append(f"log: {self.log.failed} lines could not be written")
        return lines

    def close(self) -> None:
        if self.view is not None:
            self.view.close()
        if self.tuio is not None:
            self.tuio.close()
        if self.log is not None:
            self.log.close()
