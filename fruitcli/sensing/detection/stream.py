"""Frame-by-frame detection (`Stream`): drift tracking, hysteresis, debounce, hovers and
touch IDs, each frame through the locator's layout and model; also the live loop. What
each option does: `frames_to_touches`.

Units: counts, mm, kPa.
"""

from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING, NamedTuple, Protocol

import numpy as np

from fruitcli.sensing.detection.drift import DriftTracker
from fruitcli.sensing.detection.locate import StatePath
from fruitcli.sensing.detection.methods import METHODS
from fruitcli.sensing.detection.model_fit import (
    Fitted,
    FootprintLaw,
    Window,
    recent_frames,
    refine,
)
from fruitcli.sensing.detection.touch_table import HOVER, TOUCH, TouchTable
from fruitcli.sensing.shape.touch_shape import touch_shapes

if TYPE_CHECKING:
    from fruitcli.sensing.detection.detect import Grid, Layout
    from fruitcli.sensing.detection.surface_chart import SurfaceChart
    from fruitcli.sensing.detection.two_footprints import Footprint
    from fruitcli.sensing.skin.heights import HeightModel


class StreamSettings(Protocol):
    """What a `Stream` reads of the detection settings (`settings.Settings`)."""

    @property
    def threshold_counts(self) -> float: ...
    @property
    def hysteresis_counts(self) -> float: ...
    @property
    def debounce_frames(self) -> int: ...
    @property
    def drift_rate(self) -> float: ...
    @property
    def track_gate_mm(self) -> float: ...
    @property
    def max_touches(self) -> int: ...
    @property
    def model_frames(self) -> int: ...
    @property
    def method(self) -> str: ...
    @property
    def floor(self) -> float: ...


class StreamLocator(Protocol):
    """What a `Stream` reads of its locator (`frames_to_touches.Locator`, which names
    this module, so the stream names the locator by what it reads)."""

    @property
    def settings(self) -> StreamSettings: ...

    rows: np.ndarray  # (T,) frame row of each taxel
    cols: np.ndarray
    grid: Grid
    layout: Layout
    gain: np.ndarray | None
    hover_levels: tuple[float, float] | None
    footprint: Footprint | None
    model: tuple[Window, FootprintLaw] | None
    chart: SurfaceChart | None
    noise_counts: np.ndarray | None
    heights: HeightModel
    positions_mm: np.ndarray  # (T, 3) or (S, T, 3)
    state_pressure_kpa: np.ndarray | None

    @property
    def reduced(self) -> object | None: ...  # a `fruitcli.fem.reduced.model.ReducedModel`

    def reduced_positions(self, pressure_kpa: np.ndarray) -> np.ndarray: ...


class _Peaks(NamedTuple):
    """One frame's peaks: grid coordinates i, j (n,), peak counts (n,), their N9 taxels
    `taxel9` (n, 9) (-1: none), the same with 0 for none (`tax`) and the N9 weights
    (n, 9)."""

    i: np.ndarray
    j: np.ndarray
    peak: np.ndarray
    taxel9: np.ndarray
    tax: np.ndarray
    weight: np.ndarray


class Stream:
    """Frame-by-frame detection with drift tracking, hysteresis, debounce and touch IDs."""

    def __init__(self, locator: StreamLocator, baseline: np.ndarray):
        """`locator`: a `frames_to_touches.Locator` (its layout, settings, model and
        positions); `baseline` (T,) counts."""
        self.loc = locator
        self.s = locator.settings
        self.baseline = np.asarray(baseline, dtype=float).copy()
        self.touched = False
        self.hovering = False
        self.above = 0
        self.drift = DriftTracker.per_frame(self.s.drift_rate) if self.s.drift_rate > 0 else None
        self.tracker = None
        if self.s.track_gate_mm > 0:
            from fruitcli.sensing.detection.sessions import SessionTracker

            self.tracker = SessionTracker(self.s.track_gate_mm, reuse_ids=True)
        self._cells = locator.grid.shape[0] * locator.grid.shape[1]  # padded grid cells
        self.activation = np.zeros(len(locator.rows))  # the last frame's v, undivided
        self._recent: deque[np.ndarray] = deque(maxlen=self.s.model_frames)  # for the model
        self._pos: np.ndarray | None = None  # (T, 3) mm at the pressures `_pos_key`
        self._pos_key: tuple[float, ...] | None = None
        self._path: StatePath | None = None
        self._empty = TouchTable.concat([])
        from fruitcli.sensing.detection.n9_kernel import n9_frame

        self._n9_frame = n9_frame  # the compiled N9 loop, and its buffers
        # taxel of each N9 cell of each position, 0 where none (its weight is 0)
        self._n9_taxel = np.where(locator.layout.n9_taxel < 0, 0, locator.layout.n9_taxel)
        m = self.s.max_touches
        self._scratch = np.empty(len(locator.rows))
        self._k, self._peak = np.empty(m, np.int64), np.empty(m)
        self._i, self._j, self._w = np.empty(m), np.empty(m), np.empty((m, 9))
        self._n9_frame(
            self.activation,
            locator.layout.taxel,
            locator.layout.n9,
            locator.layout.ci,
            locator.layout.cj,
            np.inf,
            0.0,
            m,
            self._scratch,
            self._k,
            self._peak,
            self._i,
            self._j,
            self._w,
        )  # load it now

    def step(
        self, values: np.ndarray, pressure_kpa: np.ndarray | None = None, frame: int = 0
    ) -> TouchTable:
        """Touches of one frame given its taxel counts (T,) (or a whole frame (R, C)): its
        activations (`_activation`), the touch and hover state it moves (`_levels`; a
        frame with neither: `_idle`), its peaks (`_peaks`), their 3D points at the
        frame's pressures, fitted by the model method (`_refine`), and their shapes,
        IDs and kinds."""
        loc = self.loc
        if values.ndim == 2:
            values = values[loc.rows, loc.cols]
        v = self._activation(values)
        vmax = float(v.max())
        levels = self._levels(vmax)
        if levels is None:
            self._idle(values, vmax)
            return self._empty
        thr, touch_thr = levels
        p = self._peaks(v, thr)
        pos = self._positions(pressure_kpa)
        n = len(p.i)
        # stacked (1, 9) @ (9, 3) products: numpy's per-touch ``w @ pos[tax]``, all at once
        pos9 = pos[p.tax]
        xyz = (p.weight[:, None, :] @ pos9)[:, 0, :]
        i, j = p.i, p.j
        extra: dict[str, np.ndarray] = {}
        if loc.model is not None and n:
            fitted = self._refine(loc.model, p, pos)
            xyz, i, j, extra = fitted.merged(xyz)
        sh = touch_shapes(v[p.tax] * (p.taxel9 >= 0), p.taxel9, pos9, xyz, loc.heights)
        ids = self.tracker.update(xyz).ids if self.tracker is not None else np.arange(n)
        kind = np.where(p.peak > touch_thr, TOUCH, HOVER).astype(np.int8)
        return TouchTable.make(
            np.full(n, frame, np.int64),
            ids,
            i,
            j,
            xyz,
            p.peak,
            sh.height_mm,
            sh.height_err_mm,
            sh.strength,
            sh.size_mm,
            kind,
            **extra,
        )

    def _activation(self, values: np.ndarray) -> np.ndarray:
        """The frame's activations v (T,) counts: its taxel counts over the baseline,
        clipped at 0 (kept in `activation` for the live view) and divided by the gains
        when detection divides; the model method keeps them unclipped in its recent
        frames."""
        loc = self.loc
        v = values - self.baseline
        if loc.model is not None:  # the model averages counts before they are clipped
            self._recent.append(v / loc.gain if loc.gain is not None else v.copy())
        np.maximum(v, 0.0, out=v)
        self.activation = v  # (T,) counts, for the live view
        if loc.gain is not None:
            v = v / loc.gain
        return v

    def _levels(self, vmax: float) -> tuple[float, float] | None:
        """(level peaks are taken above, level of a touch) in counts for a frame whose
        largest activation is `vmax`, moving the touch state (debounce, hysteresis) and
        the hover state; the touch level is inf while no touch is on (every peak is a
        hover). None when neither a touch nor a hover is on."""
        s, loc = self.s, self.loc
        low = s.threshold_counts - s.hysteresis_counts
        if self.touched:
            on = vmax > low
            thr = low
        else:
            self.above = self.above + 1 if vmax > s.threshold_counts else 0
            on = self.above >= max(s.debounce_frames, 1)
            thr = s.threshold_counts
        self.touched = on
        touch_thr = thr if on else np.inf
        if loc.hover_levels is not None:
            hover_on, hover_off = loc.hover_levels
            self.hovering = vmax > (hover_off if self.hovering else hover_on)
            if self.hovering:
                thr = min(thr, hover_off)
            on = on or self.hovering
        return (thr, touch_thr) if on else None

    def _idle(self, values: np.ndarray, vmax: float) -> None:
        """A frame with neither a touch nor a hover: the baseline drifts toward its counts
        `values` (T,) (frozen while `vmax` is above threshold - hysteresis) and the
        touch IDs end."""
        s = self.s
        if self.drift is not None:
            low = s.threshold_counts - s.hysteresis_counts
            self.drift.update(self.baseline, values, 0.0, active=vmax > low)
        if self.tracker is not None and len(self.tracker.prev_ids):
            self.tracker.end_all()

    def _peaks(self, v: np.ndarray, thr: float) -> _Peaks:
        """The frame's peaks above `thr` counts in its activations v (T,): the method's
        function on the activation grid, or the compiled sequential N9."""
        loc, s = self.loc, self.s
        method = METHODS[s.method]
        if method.find:
            flat = np.zeros((1, self._cells))
            flat[0, loc.grid.cell] = v
            t = method.finder()(flat, loc.grid, thr, s.floor, s.max_touches, loc.footprint)
            tax = np.where(t.taxel < 0, 0, t.taxel)
            return _Peaks(t.i, t.j, t.peak, t.taxel, tax, t.weight)
        lay = loc.layout
        n = self._n9_frame(
            v,
            lay.taxel,
            lay.n9,
            lay.ci,
            lay.cj,
            float(thr),
            float(s.floor),
            int(s.max_touches),
            self._scratch,
            self._k,
            self._peak,
            self._i,
            self._j,
            self._w,
        )
        k = self._k[:n]
        return _Peaks(
            self._i[:n].copy(),
            self._j[:n].copy(),
            self._peak[:n].copy(),
            lay.n9_taxel[k],
            self._n9_taxel[k],
            self._w[:n],
        )

    def _refine(self, model: tuple[Window, FootprintLaw], p: _Peaks, pos: np.ndarray) -> Fitted:
        """The model method's fit (`model_fit.refine`) of the frame's peaks `p` to each
        one's mean over the recent frames that show it, on taxel positions `pos` (T, 3)."""
        window, law = model
        history = np.asarray(self._recent)
        n = len(p.i)
        centre = p.taxel9[:, 4]
        mean, taken = recent_frames(
            history, np.full(n, len(history) - 1), centre, window, self.s.model_frames
        )
        return refine(
            np.zeros(n, np.int64),
            centre,
            p.i,
            p.j,
            p.peak,
            mean,
            window,
            lambda win: pos[win],
            law,
            p.taxel9,
            self.loc.chart,
            self.loc.noise_counts,
            taken,
            np.arange(n),
        )

    def _positions(self, pressure_kpa: np.ndarray | None) -> np.ndarray:
        """Taxel positions (T, 3) mm for this frame's pressures (cached while unchanged)."""
        pos = self.loc.positions_mm
        if self.loc.reduced is not None and pressure_kpa is not None:
            at = tuple(np.asarray(pressure_kpa, float).tolist())
            if at != self._pos_key or self._pos is None:
                self._pos, self._pos_key = self.loc.reduced_positions(np.array(at)), at
            return self._pos
        if pos.ndim == 2 or self.loc.state_pressure_kpa is None:  # one state (`Locator`)
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
