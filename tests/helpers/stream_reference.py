"""The live loop's per-frame detection before it was compiled (compared with the new
path bit for bit by tests/sensing/detection/test_stream_kernel.py)."""

import numpy as np

from fruitcli.sensing.detection.detect import n9_peaks
from fruitcli.sensing.detection.frames_to_touches import Locator
from fruitcli.sensing.detection.locate import StatePath
from fruitcli.sensing.detection.touch_table import TouchTable


class ReferenceStream:
    """`fruitcli.sensing.detection.frames_to_touches.Stream` in its plain numpy form (per
    touch), verbatim but for the gain division added since."""

    def __init__(self, locator: Locator, baseline: np.ndarray):
        self.loc = locator
        self.s = locator.settings
        self.baseline = np.asarray(baseline, dtype=float).copy()
        self.touched = False
        self.above = 0
        self.prev_xyz = np.zeros((0, 3))
        self.prev_ids = np.zeros(0, np.int64)
        g = locator.grid
        self._flat = np.zeros(g.shape[0] * g.shape[1])
        self._offs = g.offsets
        self._di = np.repeat(np.arange(-1.0, 2.0), 3)
        self._dj = np.tile(np.arange(-1.0, 2.0), 3)
        self._pos, self._pos_key, self._path = None, None, None
        self._empty = TouchTable.concat([])
        self._none_xyz, self._none_ids = np.zeros((0, 3)), np.zeros(0, np.int64)

    def step(
        self, values: np.ndarray, pressure_kpa: np.ndarray | None = None, frame: int = 0
    ) -> TouchTable:
        """Touches of one frame given its taxel counts (T,) (or a whole frame (R, C))."""
        loc, s = self.loc, self.s
        if values.ndim == 2:
            values = values[loc.rows, loc.cols]
        flat = self._flat
        v = values - self.baseline
        np.maximum(v, 0.0, out=v)
        if loc.gain is not None:
            v /= loc.gain
        flat[loc.grid.cell] = v
        vmax = float(v.max())
        low = s.threshold_counts - s.hysteresis_counts
        if self.touched:
            on = vmax > low
            thr = low
        else:
            self.above = self.above + 1 if vmax > s.threshold_counts else 0
            on = self.above >= max(s.debounce_frames, 1)
            thr = s.threshold_counts
        self.touched = on
        if not on:
            if s.drift_rate > 0 and vmax <= low:
                self.baseline += s.drift_rate * (values - self.baseline)
            self.prev_xyz, self.prev_ids = self._none_xyz, self._none_ids
            return self._empty
        if s.method == "peaks":
            t = n9_peaks(flat[None, :].copy(), loc.grid, thr, s.floor, s.max_touches)
            rows = [(t.i[n], t.j[n], t.peak[n], t.taxel[n], t.weight[n]) for n in range(len(t))]
        else:
            rows = self._sequential(flat, thr, s.floor if s.method == "n9_floor" else 0.0)
        pos = self._positions(pressure_kpa)
        n = len(rows)
        xyz = np.empty((n, 3))
        for k, (_, _, _, tax, w) in enumerate(rows):
            xyz[k] = w @ pos[np.where(tax < 0, 0, tax)]
        ids = self._ids(xyz) if s.track_gate_mm > 0 else np.arange(n)
        return TouchTable.make(
            np.full(n, frame, np.int64),
            ids,
            np.array([r[0] for r in rows]),
            np.array([r[1] for r in rows]),
            xyz,
            np.array([r[2] for r in rows]),
        )

    def _sequential(self, flat: np.ndarray, thr: float, floor: float) -> list:
        """The paper's N9 loop on one padded flat frame (zeroed in place)."""
        grid, offs = self.loc.grid, self._offs
        width = grid.shape[1]
        rows = []
        for _ in range(self.s.max_touches):
            k = int(flat.argmax())
            peak = float(flat[k])
            if peak <= thr:
                break
            idx = offs + k
            win = flat[idx]
            if floor > 0:
                win = np.maximum(win - floor, 0.0)
            w = win / win.sum()
            ci, cj = divmod(k, width)
            rows.append(
                (
                    ci - 1 + float(w @ self._di),
                    cj - 1 + float(w @ self._dj),
                    peak,
                    grid.taxel_of_cell[idx],
                    w,
                )
            )
            flat[idx] = 0.0
        flat[:] = 0.0
        return rows

    def _positions(self, pressure_kpa) -> np.ndarray:
        """Taxel positions (T, 3) mm for this frame's pressures (cached while unchanged)."""
        pos = self.loc.positions_mm
        if pos.ndim == 2:
            return pos
        key = None if pressure_kpa is None else tuple(np.asarray(pressure_kpa).tolist())
        if key != self._pos_key or self._pos is None:
            if key is None:
                self._pos = pos[0]
            else:
                if self._path is None:
                    self._path = StatePath(self.loc.state_pressure_kpa)
                s0, t = self._path.locate(np.asarray(key))
                s1 = min(s0 + 1, pos.shape[0] - 1)
                self._pos = (1 - t) * pos[s0] + t * pos[s1]
            self._pos_key = key
        return self._pos

    def _ids(self, xyz: np.ndarray) -> np.ndarray:
        from scipy.optimize import linear_sum_assignment  # slow to import: only for IDs

        ids = np.full(xyz.shape[0], -1, np.int64)
        if self.prev_xyz.shape[0] and xyz.shape[0]:
            cost = np.linalg.norm(self.prev_xyz[:, None, :] - xyz[None, :, :], axis=2)
            r, c = linear_sum_assignment(cost)
            ok = cost[r, c] <= self.s.track_gate_mm
            ids[c[ok]] = self.prev_ids[r[ok]]
        used = set(ids[ids >= 0].tolist())
        nxt = 0
        for k in np.flatnonzero(ids < 0):
            while nxt in used:
                nxt += 1
            ids[k] = nxt
            used.add(nxt)
        self.prev_xyz, self.prev_ids = xyz, ids
        return ids
