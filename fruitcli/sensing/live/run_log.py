"""The run log of `fruit live --log FILE`: touches and a status line per minute, in a
file that rotates (FILE, FILE.1 ... FILE.<backups>) so weeks of running cannot fill the
disk: at most (backups + 1) x max_bytes.

Lines: ``<UTC time> down <session> x_mm y_mm z_mm i j peak``, ``<UTC time> up <session>
<duration s> <max peak>``, ``<UTC time> status <text>`` and ``<UTC time> event <text>``
(reconnects). Units: mm, grid units, counts, s.
"""

from __future__ import annotations

import logging
import logging.handlers
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from fruitcli.sensing.detection.sessions import SessionStep

STATUS_EVERY_S = 60.0


class _CountingHandler(logging.handlers.RotatingFileHandler):
    """A rotating file whose failed writes go to `on_error` instead of a traceback."""

    def __init__(
        self,
        path: str | Path,
        max_bytes: int,
        backups: int,
        on_error: Callable[[logging.LogRecord], None],
    ):
        super().__init__(path, maxBytes=max_bytes, backupCount=backups, encoding="utf-8")
        self.on_error = on_error

    def handleError(self, record: logging.LogRecord) -> None:
        self.on_error(record)


class RunLog:
    def __init__(self, path: str | Path, max_bytes: int, backups: int):
        self.logger = logging.getLogger(f"fruit.live.{id(self)}")
        self.logger.propagate = False
        self.logger.setLevel(logging.INFO)
        # failed lines (a full disk) are counted instead of a traceback on stderr
        self.handler = _CountingHandler(path, max_bytes, backups, self._count_failure)
        fmt = logging.Formatter("%(asctime)s.%(msecs)03dZ %(message)s", "%Y-%m-%dT%H:%M:%S")
        fmt.converter = time.gmtime
        self.handler.setFormatter(fmt)
        self.failed = 0  # lines that could not be written (a full disk): counted, not fatal
        self.logger.addHandler(self.handler)
        self.open: dict[int, tuple[float, float]] = {}  # session -> (start t_s, max peak)

    def _count_failure(self, record: logging.LogRecord) -> None:
        self.failed += 1

    def frame(
        self,
        t_s: float,
        sessions: SessionStep,
        xyz_mm: np.ndarray,
        ij: np.ndarray,
        peak: np.ndarray,
    ) -> None:
        """Log the frame's touch downs and ups (sessions: a SessionStep)."""
        for k in range(len(sessions.ids)):
            s = int(sessions.ids[k])
            if sessions.new[k]:
                x, y, z = xyz_mm[k]
                self.logger.info(
                    f"down {s} {x:.2f} {y:.2f} {z:.2f} {ij[k][0]:.3f} {ij[k][1]:.3f} {peak[k]:.1f}"
                )
                self.open[s] = (t_s, float(peak[k]))
            elif s in self.open:
                t0, pk = self.open[s]
                self.open[s] = (t0, max(pk, float(peak[k])))
        self.ended(t_s, sessions.ended)

    def ended(self, t_s: float, ids: Iterable[int]) -> None:
        for s in ids:
            t0, pk = self.open.pop(int(s), (t_s, 0.0))
            self.logger.info(f"up {int(s)} {t_s - t0:.3f} {pk:.1f}")

    def status(self, text: str) -> None:
        self.logger.info(f"status {text}")

    def event(self, text: str) -> None:
        self.logger.info(f"event {text}")

    def close(self) -> None:
        self.logger.removeHandler(self.handler)
        try:
            self.handler.close()
        except (OSError, ValueError):  # the file could not be flushed: already counted
            self.failed += 1
