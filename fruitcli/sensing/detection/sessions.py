"""Touch ids across frames: a finger keeps its id from frame to frame. The one tracker
behind `fruit live`'s session ids (never reused, as TUIO wants) and
``[detection].track_gate_mm`` (the lowest id not in use, as a replay's touch rank).

Units: mm, s. Consecutive frames' touch points (3D, mm) are matched by
``scipy.optimize.linear_sum_assignment`` on their distance (or, when each touch's
nearest partner decides it, the compiled `session_kernel`, which gives the same
assignment); a pair farther apart than the gate, and every unmatched touch, starts a
new session with the next unused id (TUIO's session ids, which a client takes as a new
cursor), or with ``reuse_ids`` the lowest id no touch of the frame holds. With a gate of 0
every touch of every frame is a new session.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DEFAULT_GATE_MM = 20.0  # a finger moving 0.6 m/s at 30 frames/s; pitch 12-16 mm


@dataclass
class SessionStep:
    """One frame's sessions: ids of its touches (in their order), which are new, and the
    ids that ended (alive on the previous frame, not on this one)."""

    ids: np.ndarray  # (n,) int
    new: np.ndarray  # (n,) bool
    ended: list[int]


class SessionTracker:
    """Assign session ids to each frame's touch points (n, 3) mm."""

    def __init__(self, gate_mm: float = DEFAULT_GATE_MM, reuse_ids: bool = False):
        self.gate_mm = float(gate_mm)
        self.reuse_ids = reuse_ids
        self.next_id = 0
        self.prev_xyz = np.zeros((0, 3))
        self.prev_ids = np.zeros(0, np.int64)
        # the compiled nearest-partner path when it decides (tests: off); it numbers new
        # sessions from next_id, so not with reuse_ids
        self.fast = not reuse_ids
        if self.fast:
            from fruitcli.sensing.detection.session_kernel import nearest_match

            self._nearest = nearest_match
            one = np.zeros((1, 3))  # compiled (or loaded from the cache) now, not on a frame
            nearest_match(
                one,
                one,
                np.zeros(1, np.int64),
                0.0,
                0,
                np.empty((1, 1)),
                np.empty(1, np.int64),
                np.empty(1, bool),
            )

    def update(self, xyz_mm: np.ndarray) -> SessionStep:
        n = xyz_mm.shape[0]
        m = self.prev_xyz.shape[0]
        if self.gate_mm > 0 and n and m:
            xyz = np.ascontiguousarray(xyz_mm, dtype=float)
            cost, ids, new = np.empty((m, n)), np.empty(n, np.int64), np.empty(n, bool)
            k = (
                self._nearest(
                    self.prev_xyz, xyz, self.prev_ids, self.gate_mm, self.next_id, cost, ids, new
                )
                if self.fast
                else -1
            )
            if k >= 0:
                self.next_id += k
                return self._step(xyz_mm, ids, new)
        ids = np.full(n, -1, np.int64)
        if self.gate_mm > 0 and n and m:
            from scipy.optimize import linear_sum_assignment  # slow to import: when needed

            d = self.prev_xyz[:, None, :] - xyz_mm[None, :, :]
            cost = np.sqrt((d * d).sum(axis=2))
            r, c = linear_sum_assignment(cost)
            ok = cost[r, c] <= self.gate_mm
            ids[c[ok]] = self.prev_ids[r[ok]]
        new = ids < 0
        if self.reuse_ids:
            used, nxt = set(ids[~new].tolist()), 0
            for row in np.flatnonzero(new):
                while nxt in used:
                    nxt += 1
                ids[row] = nxt
                used.add(nxt)
            return self._step(xyz_mm, ids, new)
        k = int(new.sum())
        ids[new] = np.arange(self.next_id, self.next_id + k)
        self.next_id += k
        return self._step(xyz_mm, ids, new)

    def _step(self, xyz_mm: np.ndarray, ids: np.ndarray, new: np.ndarray) -> SessionStep:
        ended = sorted(set(self.prev_ids.tolist()) - set(ids.tolist()))
        self.prev_xyz, self.prev_ids = np.array(xyz_mm, dtype=float), ids
        return SessionStep(ids, new, ended)

    def end_all(self) -> list[int]:
        """End every alive session (the board went away); -> their ids."""
        ended = sorted(self.prev_ids.tolist())
        self.prev_xyz, self.prev_ids = np.zeros((0, 3)), np.zeros(0, np.int64)
        return ended
