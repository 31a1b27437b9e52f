"""Frames -> touches in 3D: the detection settings, a batch path and a per-frame stream.

Units: counts, mm, kPa.

The batch path (`Locator.chunks`, `Locator.batch`) is vectorized over the frames of a
chunk and used whenever no option needs state carried from frame to frame; a recording
goes through it chunk by chunk, so its memory does not grow with its length. Drift
tracking, hysteresis, debounce and touch IDs carry state, so they run frame by frame
through `Stream` (`stream`, also the live loop); both write a `touch_table.TouchTable`:

- drift tracking (``drift_rate`` r > 0, `drift.DriftTracker.per_frame`): C0 += r (C - C0)
  on frames whose every v is at most threshold - hysteresis and that are not in a touch
  (frozen while touched);
- debounce (``debounce_frames`` d): a touch starts on the d-th consecutive frame whose
  maximum v exceeds the threshold (0 and 1: at once);
- hysteresis (``hysteresis_counts`` h): once touched, touches are extracted above
  threshold - h and the touch ends when no v exceeds threshold - h (frame-level state);
- hovers (``hovers``): while no touch is on, a frame whose maximum v exceeds the hover
  threshold (default ``HOVER_NOISE_SIGMAS`` noise std of the skin) starts a hover, which
  lasts while the maximum stays above the hover threshold minus its hysteresis (default
  ``HOVER_HYSTERESIS_SIGMAS`` noise std); its peaks are extracted as touches are, at that
  level, with ``kind`` hover. During a touch, peaks between the hover level and the
  touch level are hovers too. A touch's rows never change (its peaks are extracted
  first, strongest first);
- touch IDs (``track_gate_mm`` g > 0, `sessions.SessionTracker` with ``reuse_ids``):
  previous and current 3D touch points are matched by
  ``scipy.optimize.linear_sum_assignment`` on their distance; pairs farther than g, and
  unmatched touches, get the lowest ID not in use. Without IDs, ``touch`` is the rank.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace
from typing import TYPE_CHECKING, Protocol

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.sensing.detection.detect import (
    MAX_TOUCHES,
    Grid,
    Layout,
    Touches,
    activation_grid,
    baseline_counts,
    n9_sequential,
)
from fruitcli.sensing.detection.locate import state_path_position, touches_3d
from fruitcli.sensing.detection.methods import METHODS
from fruitcli.sensing.detection.model_fit import (
    PROFILE_STEP_MM,
    Fitted,
    FootprintLaw,
    Window,
    recent_frames,
    refine,
)
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.detection.stream import Stream
from fruitcli.sensing.detection.touch_table import TouchTable
from fruitcli.sensing.frames.board import taxel_cells
from fruitcli.sensing.shape.touch_shape import Shapes, frame_shapes
from fruitcli.tables import Taxels

if TYPE_CHECKING:
    from fruitcli.scene import BoardSection
    from fruitcli.sensing.detection.surface_chart import ClosestPoints, SurfaceChart
    from fruitcli.sensing.detection.two_footprints import Footprint
    from fruitcli.sensing.skin.heights import HeightModel

CHUNK_FRAMES = 8192  # frames read and detected together (16 MB of counts at 21 x 12)
# the model method weighs each taxel by its own noise, measured in the baseline frames
# when there are at least this many (else the skin's one value)
MIN_NOISE_FRAMES = 10
MIN_NOISE_COUNTS = 0.3  # a floor: the std of a count rounded to an integer


def detect(
    frames: np.ndarray,
    baseline: np.ndarray,
    grid: Grid,
    layout: Layout,
    threshold: float,
    method: str = "n9",
    floor: float = 0.0,
    max_touches: int = MAX_TOUCHES,
    gain: np.ndarray | None = None,
    footprint: Footprint | None = None,
) -> Touches:
    """Touches of frames (N, rows * cols) counts against C0 (T,) by the scene's
    ``[detection].method`` (`methods.METHODS`): the sequential N9, or the method's `find`
    function on the activation grids (fit2's with the skin's `two_footprints.Footprint`
    `footprint`); the model method's touches
    are the sequential N9's here, refined where the taxels' positions are known
    (`Locator`). Activations are divided by `gain` (T,) when given."""
    m = METHODS.get(method)
    if m is None:
        raise FrameError(f"detection method: expected one of {', '.join(METHODS)}, got {method!r}")
    floor = floor if m.floor else 0.0
    if not m.find:
        return n9_sequential(frames, baseline, layout, threshold, floor, max_touches, gain)
    values = np.take(frames, layout.frame_cell, axis=1)
    flat = activation_grid(values, baseline, grid, gain)
    return m.finder()(flat, grid, threshold, floor, max_touches, footprint)


class ReducedTaxels(Protocol):
    """What a `Locator` and its callers read of a reduced model
    (`fruitcli.fem.reduced.model.ReducedModel`): its chambers' range lo, hi (K,) kPa
    and the taxel positions at pressures."""

    @property
    def lo(self) -> np.ndarray: ...
    @property
    def hi(self) -> np.ndarray: ...
    def taxels(self, pressure_kpa: np.ndarray) -> np.ndarray: ...
    def outside(self, pressure_kpa: np.ndarray) -> np.ndarray: ...
    def describe(self) -> str: ...


class Locator:
    """Detection and 3D location for one taxel layout, board and set of positions.

    `positions_mm` is (T, 3) (one state) or (S, T, 3) with `state_pressure_kpa` (S, K):
    then each frame's pressures pick its place on the state path. With `reduced` (a
    `fruitcli.fem.reduced.model.ReducedModel` of these taxels), each frame's pressures give
    its taxels' positions through the reduced model instead (clamped to its range).
    `gain` (T,): divide each taxel's activation by it before detection
    (`fruitcli.sensing.detection.detect`; None: off, the paper). `heights`: the skin's
    `fruitcli.sensing.skin.heights.HeightModel` for strengths, sizes and heights
    (default: the default skin's gap law).
    """

    def __init__(
        self,
        taxels: Taxels,
        board: BoardSection,
        positions_mm: np.ndarray,
        settings: Settings,
        state_pressure_kpa: np.ndarray | None = None,
        where: str = "taxels",
        reduced: ReducedTaxels | None = None,
        gain: np.ndarray | None = None,
        heights: HeightModel | None = None,
    ):
        if heights is None:
            from fruitcli.sensing.skin.forward import DEFAULT_PARAMS
            from fruitcli.sensing.skin.heights import gap_law

            heights = gap_law(DEFAULT_PARAMS, footprint=settings.footprint)
        self.heights: HeightModel = heights
        self.hover_levels = (
            settings.hover_levels(heights.noise_std_counts) if settings.hovers else None
        )
        if settings.method not in METHODS:
            raise FrameError(
                f"[detection].method: expected one of {', '.join(METHODS)}, got {settings.method!r}"
            )
        self.footprint: Footprint | None = None  # fit2's
        if METHODS[settings.method].refine == "fit2":
            from fruitcli.sensing.detection.two_footprints import Footprint

            law = FootprintLaw.of(heights, settings.method)  # the skin's own, as the model's
            self.footprint = Footprint.from_taxels(
                law.sigma_mm,
                law.noise_std_counts,
                taxels.i,
                taxels.j,
                taxels.xyz_mm,
                law.profile,
                PROFILE_STEP_MM,
            )
        self.reduced = reduced
        self.taxels, self.board, self.settings = taxels, board, settings
        self.gain = None if gain is None else np.asarray(gain, dtype=float)
        self.model: tuple[Window, FootprintLaw] | None = None  # the model method's
        if METHODS[settings.method].refine == "model":
            law = FootprintLaw.of(heights)
            if self.gain is not None:  # activations divided by the gains already
                law = replace(law, gain=None)
            self.model = (Window(taxels.i, taxels.j), law)
        self.chart: SurfaceChart | None = None  # the body's surface, model method (`use_surface`)
        self.noise_counts: np.ndarray | None = None  # (T,) noise std in the baseline frames
        self.rows, self.cols = taxel_cells(taxels, board, where)
        self.grid = Grid.from_ij(taxels.i, taxels.j)
        self.frame_shape = (board.rows, board.cols)
        self.layout = Layout.build(self.grid, self.rows * board.cols + self.cols)
        self.positions_mm = np.asarray(positions_mm, dtype=float)
        self.state_pressure_kpa = state_pressure_kpa
        if self.positions_mm.ndim == 3 and state_pressure_kpa is None:
            raise FrameError("per-state positions need the states' pressures")

    def use_surface(self, normal: np.ndarray, distance: ClosestPoints) -> None:
        """Let the model method run its touches over the body's surface in this locator's
        one state (its faces' unit normals (F, 3) and their `SurfaceDistance`, as a
        `SurfaceProjector` keeps them) instead of the surface its taxels span
        (`surface_chart`). Only for one state and no reduced model: a chart
        is made once per peak taxel and kept."""
        if self.model is None or self.positions_mm.ndim != 2 or self.reduced is not None:
            return
        from fruitcli.sensing.detection.surface_chart import SurfaceChart

        half = int(self.model[0].di.max())
        self.chart = SurfaceChart(normal, distance, half)

    def reduced_positions(self, pressure_kpa: np.ndarray) -> np.ndarray:
        """Taxel positions (T, 3), or (n, T, 3) for (n, K) kPa, from the reduced model at
        the pressures clamped to its range."""
        r = self.reduced
        assert r is not None, "reduced_positions needs a reduced model"
        return r.taxels(np.clip(np.asarray(pressure_kpa, float), r.lo, r.hi))

    def values(self, frames: np.ndarray) -> np.ndarray:
        """Counts of the taxel cells (N, T) from frames (N, R, C)."""
        cell = self.rows * frames.shape[2] + self.cols
        return np.take(frames.reshape(frames.shape[0], -1), cell, axis=1)

    def baseline(
        self, frames: np.ndarray, where: str = "frames", n_frames: int | None = None
    ) -> np.ndarray:
        """C0 per taxel (T,) from the first K frames; `frames` may hold only those, with
        `n_frames` the recording's length. For the model method it also keeps each
        taxel's noise std in those frames (`noise_counts`, gains divided out as the
        activations are)."""
        k = self.settings.baseline_frames
        values = self.values(frames[: max(k, 1)])
        c0 = baseline_counts(values, k, where, frames.shape[0] if n_frames is None else n_frames)
        if self.model is not None and k >= MIN_NOISE_FRAMES:
            std = values[:k].std(axis=0, ddof=1)
            self.noise_counts = np.maximum(
                std if self.gain is None else std / self.gain, MIN_NOISE_COUNTS
            )
        return c0

    def _path(
        self, pressure_kpa: np.ndarray | None, n: int
    ) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
        """(segment (n,), fraction (n,)) of each of n frames on the state path at its
        pressures (the first state without them); (None, None) for one state."""
        if self.positions_mm.ndim == 2 or self.state_pressure_kpa is None:  # one state
            return None, None
        if pressure_kpa is None:
            return np.zeros(n, np.int64), np.zeros(n)
        return state_path_position(pressure_kpa, self.state_pressure_kpa)

    def chunks(
        self,
        read: Callable[[int, int], np.ndarray],
        n_frames: int,
        baseline: np.ndarray,
        pressure_kpa: np.ndarray | None = None,
        size: int = CHUNK_FRAMES,
        then: Callable | None = None,
        workers: int = 1,
    ) -> Iterator:
        """Touches of frames 0 .. n_frames - 1, `size` at a time: ``read(start, count)``
        gives frames (count, R, C); frame indices count over the whole recording and
        `pressure_kpa` (N, K) covers all N frames. Yields each chunk's `TouchTable`, or
        ``then(table)`` computed in the worker. Stateless settings spread the chunks over
        `workers` threads (the compiled N9 loop and numpy release the GIL), in order
        (`_chunk`); stateful ones run through one `Stream` carried across the chunks
        (`_streamed`)."""
        finish = then or (lambda table: table)
        starts = range(0, n_frames, size)
        if self.settings.stateful:
            yield from self._streamed(read, starts, size, baseline, pressure_kpa, finish)
            return
        path = self._path(pressure_kpa, n_frames)

        def job(start: int):
            return finish(self._chunk(read, start, size, baseline, pressure_kpa, path))

        yield from _in_order(job, starts, workers)

    def _streamed(
        self,
        read: Callable[[int, int], np.ndarray],
        starts: range,
        size: int,
        baseline: np.ndarray,
        pressure_kpa: np.ndarray | None,
        finish: Callable,
    ) -> Iterator:
        """``finish(table)`` of each chunk's touches, its frames one by one through a
        `Stream` that carries its state from chunk to chunk."""
        stream = Stream(self, baseline)
        for start in starts:
            frames = read(start, size)
            yield finish(
                TouchTable.concat(
                    [
                        stream.step(
                            f,
                            None if pressure_kpa is None else pressure_kpa[start + n],
                            start + n,
                        )
                        for n, f in enumerate(self.values(frames))
                    ]
                )
            )

    def _chunk(
        self,
        read: Callable[[int, int], np.ndarray],
        start: int,
        size: int,
        baseline: np.ndarray,
        pressure_kpa: np.ndarray | None,
        path: tuple[np.ndarray, np.ndarray] | tuple[None, None],
    ) -> TouchTable:
        """Touches of the chunk of up to `size` frames from `start`, all at once: detected
        (`detect`), placed at each frame's taxel positions (`_points`; `path`: each
        frame's place on the state path, `_path`), fitted by the model method
        (`_refine`) and given their shapes (`_shapes`)."""
        frames = read(start, size)
        if tuple(frames.shape[1:]) != self.frame_shape:
            raise FrameError(
                f"frames of shape {tuple(frames.shape[1:])}, expected "
                f"{self.frame_shape[0]} x {self.frame_shape[1]} per [board]"
            )
        flat = frames.reshape(frames.shape[0], -1)
        s = self.settings
        t = detect(
            flat,
            baseline,
            self.grid,
            self.layout,
            s.threshold_counts,
            s.method,
            s.floor,
            s.max_touches,
            self.gain,
            self.footprint,
        )
        seg, frac = path
        end = start + frames.shape[0]
        if seg is not None and frac is not None:
            seg, frac = seg[start:end], frac[start:end]
        xyz, pos9, taxel_points = self._points(t, start, pressure_kpa, seg, frac)
        i, j = t.i, t.j
        extra: dict[str, np.ndarray] = {}
        if self.model is not None and len(t):
            v = np.take(flat, self.layout.frame_cell, axis=1)
            history = self._history(read, start, v)
            fitted = self._refine(self.model, t, history, baseline, taxel_points)
            xyz, i, j, extra = fitted.merged(xyz)
        sh = self._shapes(flat, t, pos9, xyz, baseline)
        return TouchTable.make(
            t.frame + start,
            t.rank,
            i,
            j,
            xyz,
            t.peak,
            sh.height_mm,
            sh.height_err_mm,
            sh.strength,
            sh.size_mm,
            **extra,
        )

    def _points(
        self,
        t: Touches,
        start: int,
        pressure_kpa: np.ndarray | None,
        seg: np.ndarray | None,
        frac: np.ndarray | None,
    ) -> tuple[np.ndarray, np.ndarray | None, Callable[[np.ndarray], np.ndarray]]:
        """(points (n, 3) mm, N9 taxels' positions (n, 9, 3) mm or None where they are
        rows of the one state's `positions_mm`, ``taxel_points(win)`` the positions (n,
        K, 3) of taxels win (n, K) of each touch) of the chunk's touches `t` (its first
        frame `start`): from the reduced model at each frame's pressures when there is
        one, else on the state path (`seg`, `frac` per chunk frame) or the one state."""
        tax = np.where(t.taxel < 0, 0, t.taxel)
        if self.reduced is not None and pressure_kpa is not None:
            pos = self.reduced_positions(pressure_kpa[start + t.frame])  # (n, T, 3)
            pos9 = pos[np.arange(len(tax))[:, None], tax]

            def reduced_points(win: np.ndarray) -> np.ndarray:
                return pos[np.arange(len(win))[:, None], win]

            return np.einsum("nk,nkd->nd", t.weight, pos9), pos9, reduced_points

        def taxel_points(win: np.ndarray) -> np.ndarray:
            return self._taxel_points(win, t.frame, seg, frac)

        xyz = touches_3d(t, self.positions_mm, seg, frac)
        return xyz, None if seg is None else taxel_points(tax), taxel_points

    def _shapes(
        self,
        flat: np.ndarray,
        t: Touches,
        pos9: np.ndarray | None,
        xyz: np.ndarray,
        baseline: np.ndarray,
    ) -> Shapes:
        """Heights, strengths and sizes (`frame_shapes`) of touches `t` at points xyz (n,
        3) mm of frames `flat` (N, R * C) counts, from their N9 taxels' positions pos9
        (n, 9, 3) (None: rows of the one state's `positions_mm`)."""
        if pos9 is None:
            points, rows = self.positions_mm, np.where(t.taxel < 0, 0, t.taxel)
        else:
            points, rows = pos9.reshape(-1, 3), np.arange(pos9.shape[0] * 9).reshape(-1, 9)
        return frame_shapes(
            flat,
            t.frame,
            self.layout.frame_cell,
            baseline,
            self.gain,
            t.taxel,
            points,
            rows,
            xyz,
            self.heights,
        )

    def _history(
        self, read: Callable[[int, int], np.ndarray], start: int, values: np.ndarray
    ) -> tuple[np.ndarray, int]:
        """Taxel counts (H, T) of the frames from `start` with up to ``model_frames - 1``
        frames before the chunk read again (fewer at the recording's start), and how many
        came before."""
        before = min(self.settings.model_frames - 1, start)
        if before <= 0:
            return values, 0
        earlier = read(start - before, before)
        cells = earlier.reshape(earlier.shape[0], -1)
        return np.vstack([np.take(cells, self.layout.frame_cell, axis=1), values]), before

    def _refine(
        self,
        model: tuple[Window, FootprintLaw],
        t: Touches,
        history: tuple[np.ndarray, int],
        baseline: np.ndarray,
        taxel_points: Callable[[np.ndarray], np.ndarray],
    ) -> Fitted:
        """The model method's fit (`model_fit.refine`, its window and law `model`) of
        touches `t` of frames whose taxel counts are history[0] (H, T), the chunk's frames
        after its first history[1] rows (`_history`); ``taxel_points(win)`` gives
        positions (n, K, 3)."""
        values, before = history
        v = values - baseline
        if self.gain is not None:
            v = v / self.gain
        window, law = model
        mean, taken = recent_frames(
            v, t.frame + before, t.taxel[:, 4], window, self.settings.model_frames
        )
        return refine(
            t.frame,
            t.taxel[:, 4],
            t.i,
            t.j,
            t.peak,
            mean,
            window,
            taxel_points,
            law,
            t.taxel,
            self.chart,
            self.noise_counts,
            taken,
            np.arange(len(t)),
        )

    def _taxel_points(
        self,
        tax: np.ndarray,
        frame: np.ndarray,
        seg: np.ndarray | None,
        frac: np.ndarray | None,
    ) -> np.ndarray:
        """Positions (n, K, 3) mm of taxels `tax` (n, K) (a touch's N9 or window) of
        touches in frames `frame` (n,) (on the state path `seg`, `frac` when positions
        are per state)."""
        pos = self.positions_mm
        if pos.ndim == 2:
            return pos[tax]
        if seg is None or frac is None:
            raise FrameError("per-state positions need each frame's place on the state path")
        s0 = seg[frame]
        s1 = np.minimum(s0 + 1, pos.shape[0] - 1)
        t = frac[frame][:, None, None]
        flat, per_state = pos.reshape(-1, 3), pos.shape[1]
        here = flat.take(s0[:, None] * per_state + tax, axis=0)
        after = flat.take(s1[:, None] * per_state + tax, axis=0)
        here *= 1.0 - t
        after *= t
        here += after
        return here

    def batch(
        self,
        frames: np.ndarray,
        baseline: np.ndarray,
        pressure_kpa: np.ndarray | None = None,
        size: int = CHUNK_FRAMES,
    ) -> TouchTable:
        """All touches of frames (N, R, C) in memory, `size` at a time."""
        return TouchTable.concat(
            list(
                self.chunks(
                    lambda a, k: frames[a : a + k], frames.shape[0], baseline, pressure_kpa, size
                )
            )
        )


def _in_order(job: Callable, items: Iterable, workers: int) -> Iterator:
    """job(item) for every item, run on `workers` threads, yielded in the items' order;
    at most 2 * workers items are in flight, so finished results do not pile up."""
    if workers <= 1:
        yield from map(job, items)
        return
    with ThreadPoolExecutor(workers) as pool:
        pending: deque[Future] = deque()
        try:
            for item in items:
                pending.append(pool.submit(job, item))
                if len(pending) >= 2 * workers:
                    yield pending.popleft().result()
            while pending:
                yield pending.popleft().result()
        finally:
            for f in pending:
                f.cancel()
