"""Exact N9 centroid and multitouch outputs on hand-made frames (paper Sec. III-B)."""

from dataclasses import replace

import numpy as np
import pytest

from fruitcli.errors import FrameError
from fruitcli.sensing.detection.detect import Grid, activation_grid, local_peaks
from fruitcli.sensing.detection.frames_to_touches import Locator, Stream
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.frames.board import default_board, taxel_cells
from fruitcli.tables import Taxels

BASE = 500  # counts at rest in every cell


def make_taxels(rows=5, cols=6, missing=((4, 5),)):
    ij = [(i, j) for i in range(rows) for j in range(cols) if (i, j) not in missing]
    i = np.array([a for a, _ in ij])
    j = np.array([b for _, b in ij])
    xyz = np.stack([16.0 * j, 12.0 * i, 0.5 * i * j], axis=1)
    return Taxels(np.arange(len(ij)), i, j, xyz)


def frame_with(cells: dict, rows=21, cols=12):
    f = np.full((rows, cols), BASE, dtype=np.int64)
    for (r, c), v in cells.items():
        f[r, c] += v
    return f


def run(frames, taxels=None, **kw):
    taxels = taxels or make_taxels()
    settings = Settings(baseline_frames=1, **kw)
    loc = Locator(taxels, default_board(), taxels.xyz_mm, settings)
    base = np.full(len(taxels), float(BASE))
    return loc.batch(np.asarray(frames), base)


def test_single_interior_touch_exact_centroid_and_3d():
    t = run([frame_with({(2, 3): 40, (1, 3): 20, (2, 4): 10})])
    assert len(t) == 1
    assert t.i[0] == pytest.approx(2 - 20 / 70)
    assert t.j[0] == pytest.approx(3 + 10 / 70)
    assert t.peak[0] == 40
    # the same weights on the 3D taxels (eq. 7)
    w = np.array([40, 20, 10]) / 70
    pts = np.array([[48, 24, 3.0], [48, 12, 1.5], [64, 24, 4.0]])
    assert t.xyz_mm[0] == pytest.approx(w @ pts)


def test_corner_touch_off_grid_cells_count_zero():
    t = run([frame_with({(0, 0): 30, (0, 1): 10, (1, 1): 10})])
    assert (t.i[0], t.j[0]) == pytest.approx((10 / 50, 20 / 50))


def test_missing_taxel_and_cells_outside_the_grid_are_ignored():
    # (4, 5) has no taxel; (10, 10) is outside the taxel grid: huge counts there are ignored
    t = run([frame_with({(4, 4): 30, (4, 5): 500, (3, 5): 10, (10, 10): 900})])
    assert len(t) == 1
    assert (t.i[0], t.j[0]) == pytest.approx((4 - 10 / 40, 4 + 10 / 40))


def test_two_touches_two_taxels_apart_sequential_zeroes_shared_cells():
    f = frame_with({(2, 1): 50, (2, 2): 15, (2, 3): 40, (2, 4): 10})
    t = run([f])
    assert len(t) == 2 and list(t.touch) == [0, 1]
    assert (t.i[0], t.j[0]) == pytest.approx((2, 1 + 15 / 65))
    # (2, 2) was zeroed with the first N9, so the second centroid leans right only
    assert (t.i[1], t.j[1]) == pytest.approx((2, 3 + 10 / 50))
    assert list(t.peak) == [50, 40]


def test_peaks_method_is_order_independent():
    f = frame_with({(2, 1): 50, (2, 2): 15, (2, 3): 40, (2, 4): 10})
    t = run([f], method="peaks")
    assert len(t) == 2
    assert (t.i[0], t.j[0]) == pytest.approx((2, 1 + 15 / 65))
    assert (t.i[1], t.j[1]) == pytest.approx((2, 3 + (10 - 15) / 65))


def test_ties_go_to_the_first_cell_in_row_major_order():
    t = run([frame_with({(3, 3): 30, (1, 4): 30})])
    assert len(t) == 2
    assert (t.i[0], t.j[0]) == (1.0, 4.0)
    assert (t.i[1], t.j[1]) == (3.0, 3.0)


def test_plateau_gives_one_peak():
    g = Grid.from_ij(np.repeat(np.arange(3), 3), np.tile(np.arange(3), 3))
    flat = activation_grid(np.array([[0, 30, 30, 0, 0, 0, 0, 0, 0.0]]), np.zeros(9), g)
    f, cell = local_peaks(flat, g, 20.0)
    assert f.tolist() == [0] and cell.tolist() == [1 * 5 + 2]


def test_threshold_is_strict_and_negative_activation_clipped():
    t = run([frame_with({(2, 2): 20, (2, 3): -50})])
    assert len(t) == 0
    t = run([frame_with({(2, 2): 21, (2, 3): -50})])
    assert (t.i[0], t.j[0]) == (2.0, 2.0)


def test_n9_floor_subtracts_before_weighting():
    t = run([frame_with({(2, 2): 40, (2, 3): 10})], method="n9_floor", noise_floor_counts=5)
    assert t.j[0] == pytest.approx(2 + 5 / 40)
    with pytest.raises(FrameError, match="below the threshold"):
        run([frame_with({(2, 2): 40})], method="n9_floor", noise_floor_counts=25)


def test_batch_is_vectorized_over_frames_and_matches_frame_by_frame():
    rng = np.random.default_rng(3)
    cells = rng.integers(0, [5, 6], size=(50, 2, 2))
    vals = rng.integers(10, 80, size=(50, 2))
    frames = np.stack(
        [
            frame_with({tuple(c[0]): v[0]}) + frame_with({tuple(c[1]): v[1]}) - BASE
            for c, v in zip(cells, vals, strict=True)
        ]
    )
    whole = run(frames)
    per = [run(frames[n : n + 1]) for n in range(50)]
    assert len(whole) == sum(len(p) for p in per)
    k = 0
    for n, p in enumerate(per):
        for m in range(len(p)):
            assert whole.frame[k] == n
            assert whole.i[k] == p.i[m] and whole.j[k] == p.j[m]
            k += 1


def test_board_mapping_flip_transpose_and_outside():
    tx = make_taxels(2, 3, missing=())
    board = replace(default_board(), flip_i=True, offset_j=2)
    r, c = taxel_cells(tx, board)
    assert r.tolist() == [20, 20, 20, 19, 19, 19] and c.tolist() == [2, 3, 4, 2, 3, 4]
    r, c = taxel_cells(tx, replace(default_board(), transpose=True))
    assert r.tolist() == [0, 1, 2, 0, 1, 2] and c.tolist() == [0, 0, 0, 1, 1, 1]
    with pytest.raises(
        FrameError,
        match=r"taxel id 2 \(i=0, j=2\) maps to frame cell "
        r"\(0, 12\), outside the 21 x 12 frame",
    ):
        taxel_cells(tx, replace(default_board(), offset_j=10), "t.csv")


def _stream(frames, **kw):
    tx = make_taxels()
    loc = Locator(tx, default_board(), tx.xyz_mm, Settings(baseline_frames=1, **kw))
    return loc.batch(np.asarray(frames), np.full(len(tx), float(BASE)))


def test_debounce_delays_the_touch_start():
    frames = [frame_with({(2, 2): 30})] * 4
    assert _stream(frames, debounce_frames=3).frame.tolist() == [2, 3]
    assert _stream(frames).frame.tolist() == [0, 1, 2, 3]


def test_hysteresis_keeps_a_touch_until_below_threshold_minus_h():
    vals = [30, 18, 12, 18]
    frames = [frame_with({(2, 2): v}) for v in vals]
    assert _stream(frames, hysteresis_counts=5).frame.tolist() == [0, 1]
    assert _stream(frames).frame.tolist() == [0]


def test_drift_tracking_is_frozen_while_touched():
    tx = make_taxels()
    loc = Locator(tx, default_board(), tx.xyz_mm, Settings(baseline_frames=1, drift_rate=0.5))
    s = Stream(loc, np.full(len(tx), float(BASE)))
    k = int(np.flatnonzero((tx.i == 2) & (tx.j == 2))[0])
    s.step(frame_with({(2, 2): 8}))  # untouched: baseline follows half way
    assert s.baseline[k] == BASE + 4
    s.step(frame_with({(2, 2): 60}))  # touched: frozen
    assert s.baseline[k] == BASE + 4
    s.step(frame_with({(2, 2): 4}))
    assert s.baseline[k] == BASE + 4


def test_touch_ids_follow_touches_within_the_gate():
    # touch A moves one taxel right each frame (16 mm); B appears in frame 1
    frames = [
        frame_with({(1, 1): 50}),
        frame_with({(1, 2): 50, (4, 1): 40}),
        frame_with({(1, 3): 50, (4, 1): 45}),
    ]
    t = _stream(frames, track_gate_mm=20.0)
    assert t.frame.tolist() == [0, 1, 1, 2, 2]
    assert t.touch.tolist() == [0, 0, 1, 0, 1]
    # A lifts, B jumps 32 mm: within a 40 mm gate B keeps ID 1, beyond a 10 mm gate it is
    # a new touch and gets the lowest free ID
    frames = [
        frame_with({(1, 1): 50}),
        frame_with({(1, 1): 50, (4, 1): 40}),
        frame_with({(4, 3): 40}),
    ]
    assert _stream(frames, track_gate_mm=40.0).touch.tolist() == [0, 0, 1, 1]
    assert _stream(frames, track_gate_mm=10.0).touch.tolist() == [0, 0, 1, 0]


def test_pressure_interpolates_between_states():
    tx = make_taxels()
    pos = np.stack([tx.xyz_mm, tx.xyz_mm + [0, 0, 10.0], tx.xyz_mm + [0, 0, 30.0]])
    press = np.array([[0.0], [10.0], [20.0]])
    loc = Locator(tx, default_board(), pos, Settings(baseline_frames=1), press)
    f = frame_with({(2, 2): 40})
    t = loc.batch(
        np.stack([f, f, f]), np.full(len(tx), float(BASE)), np.array([[5.0], [15.0], [99.0]])
    )
    assert t.xyz_mm[:, 2] == pytest.approx(2.0 + np.array([5.0, 20.0, 30.0]))


def test_stream_matches_batch_and_state_path_matches_vectorized():
    from fruitcli.sensing.detection.locate import StatePath, state_path_position

    rng = np.random.default_rng(5)
    tx = make_taxels()
    pos = np.stack([tx.xyz_mm + [0, 0, 3.0 * s] for s in range(4)])
    press = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 8.0]])
    loc = Locator(tx, default_board(), pos, Settings(baseline_frames=1), press)
    frames = np.stack(
        [
            frame_with({(int(a), int(b)): int(v), (int(c), int(d)): int(u)})
            for a, b, v, c, d, u in zip(
                rng.integers(5, size=40),
                rng.integers(6, size=40),
                rng.integers(0, 90, 40),
                rng.integers(5, size=40),
                rng.integers(6, size=40),
                rng.integers(0, 90, 40),
                strict=True,
            )
        ]
    )
    kpa = rng.uniform(-1, 9, (40, 2))
    base = np.full(len(tx), float(BASE))
    whole = loc.batch(frames, base, kpa)
    stream = Stream(loc, base)
    parts = [stream.step(f, kpa[n], n) for n, f in enumerate(loc.values(frames))]
    assert np.array_equal(whole.frame, np.concatenate([p.frame for p in parts]))
    assert np.allclose(whole.xyz_mm, np.concatenate([p.xyz_mm for p in parts]))
    assert np.allclose(whole.i, np.concatenate([p.i for p in parts]))
    seg, frac = state_path_position(kpa, press)
    path = StatePath(press)
    for n in range(40):
        assert path.locate(kpa[n]) == (seg[n], pytest.approx(frac[n]))
