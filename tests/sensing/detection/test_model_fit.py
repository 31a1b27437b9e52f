"""The model method (`model_fit`): frames made from a footprint at a known point come back
within the fit's own uncertainty; frames no footprint explains keep N9's point, flagged;
its columns round-trip through touches.csv and the live JSON lines."""

import csv
import json

import numpy as np
import pytest

from fruitcli.errors import FrameError
from fruitcli.sensing.detection.frames_to_touches import Locator, Stream
from fruitcli.sensing.detection.model_fit import (
    FIT_MODEL,
    FIT_N9,
    FootprintLaw,
    Window,
)
from fruitcli.sensing.detection.model_kernel import prepare
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.detection.touch_table import TouchTable
from fruitcli.sensing.frames.board import default_board, taxel_cells
from fruitcli.sensing.skin.heights import GapLaw
from fruitcli.tables import Taxels

BASE = 500.0
SIGMA_MM = 6.5  # footprint of the frames and of the law the fit is given
LAW = GapLaw(60.0, 2.0, SIGMA_MM, 1.0)


def grid_taxels(rows=6, cols=7, bend_radius_mm=None):
    """rows x cols taxels 16 mm (i) x 12 mm (j) apart, flat or wrapped around a cylinder."""
    i, j = (a.ravel() for a in np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"))
    x, y = 16.0 * i, 12.0 * j
    if bend_radius_mm is None:
        xyz = np.stack([x, y, np.zeros(i.size)], axis=1)
    else:
        th = (x - x.mean()) / bend_radius_mm
        r = bend_radius_mm
        xyz = np.stack([r * np.sin(th), y, r * np.cos(th) - r], axis=1)
    return Taxels(np.arange(i.size), i, j, xyz)


def frame_of(taxels, point, amplitude=100.0, sigma=SIGMA_MM, noise=0.0, seed=0):
    """A board frame (21, 12) whose taxels read amplitude * Gaussian(3D distance)."""
    d = np.linalg.norm(taxels.xyz_mm - point, axis=1)
    v = amplitude * np.exp(-0.5 * (d / sigma) ** 2)
    v = v + np.random.default_rng(seed).normal(0.0, noise, v.size)
    rows, cols = taxel_cells(taxels, default_board(), "taxels")
    f = np.full((21, 12), BASE)
    f[rows, cols] += np.maximum(v, 0.0)
    return np.round(f).astype(np.int64)


def locate(taxels, frames, method="model", heights=LAW):
    loc = Locator(taxels, default_board(), taxels.xyz_mm, Settings(method=method), heights=heights)
    return loc.batch(np.asarray(frames), np.full(len(taxels), BASE))


@pytest.mark.parametrize(
    "point",
    [
        (40.0, 30.0, 0.0),  # between four crossings
        (48.0, 18.0, 0.0),  # on a crossing's row, half way to the next
        (2.0, 40.0, 0.0),  # the grid's first row, a little off it
        (80.0, 71.0, 0.0),  # the grid's far corner
    ],
)
def test_a_footprint_at_a_known_point_comes_back_within_its_uncertainty(point):
    taxels = grid_taxels()
    frames = [frame_of(taxels, np.array(point), noise=1.0, seed=s) for s in range(20)]
    t = locate(taxels, frames)
    n9 = locate(taxels, frames, method="n9")
    assert len(t) == 20 and (t.fit == FIT_MODEL).all()
    err = np.linalg.norm(t.xyz_mm - point, axis=1)
    # within 3 sigma of its own uncertainty, and better than N9 on average
    assert (err <= 3.0 * t.pos_err_mm + 0.05).all()
    assert err.mean() < np.linalg.norm(n9.xyz_mm - point, axis=1).mean()
    assert 0.3 < np.median(t.residual) < 2.0  # the noise is what is left


def test_without_noise_the_point_is_exact():
    taxels = grid_taxels()
    point = np.array([37.3, 27.1, 0.0])
    d = np.linalg.norm(taxels.xyz_mm - point, axis=1)
    v = 60.0 * np.exp(-0.5 * (d / SIGMA_MM) ** 2)
    loc = Locator(taxels, default_board(), taxels.xyz_mm, Settings(method="model"), heights=LAW)
    stream = Stream(loc, np.zeros(len(taxels)))
    t = stream.step(v)
    assert t.fit[0] == FIT_MODEL
    assert t.xyz_mm[0] == pytest.approx(point, abs=0.02)  # the profile's sampling
    assert (t.i[0], t.j[0]) == pytest.approx((37.3 / 16.0, 27.1 / 12.0), abs=0.002)


def test_on_a_bent_body_the_point_stays_on_the_taxels_surface():
    radius = 50.0
    taxels = grid_taxels(bend_radius_mm=radius)
    th = (40.0 - 40.0) / radius + 0.13  # a point 6.5 mm round the cylinder from the middle
    point = np.array([radius * np.sin(th), 30.0, radius * np.cos(th) - radius])
    frames = [frame_of(taxels, point, noise=1.0, seed=s) for s in range(20)]
    t = locate(taxels, frames)
    assert (t.fit == FIT_MODEL).all()
    err = np.linalg.norm(t.xyz_mm - point, axis=1)
    assert (err <= 3.0 * t.pos_err_mm + 0.05).all()
    # on the cylinder (radius 50 mm) to within a tenth of a millimetre
    r = np.hypot(t.xyz_mm[:, 0], t.xyz_mm[:, 2] + radius)
    assert np.abs(r - radius).max() < 0.15


def test_frames_no_footprint_explains_keep_the_n9_point_flagged():
    taxels = grid_taxels()
    rows, cols = taxel_cells(taxels, default_board(), "taxels")
    spike = np.full((21, 12), int(BASE))  # one taxel alone: narrower than any footprint
    k = int(np.flatnonzero((taxels.i == 2) & (taxels.j == 3))[0])
    spike[rows[k], cols[k]] += 100
    # a touch under noise 12 times the skin's: the reduced chi^2 test
    noisy = [frame_of(taxels, np.array([40.0, 30.0, 0.0]), noise=12.0, seed=s) for s in range(8)]
    frames = [spike, *noisy]
    t = locate(taxels, frames)
    n9 = locate(taxels, frames, method="n9")
    assert t.fit[t.frame == 0].tolist() == [FIT_N9]  # by the width test
    first = (t.frame > 0) & (t.touch == 0)  # the touch, not the noise's peaks
    assert first.sum() == 8
    assert t.residual[first].min() ** 2 > 9.0
    assert (t.fit[first] == FIT_N9).all()
    kept = t.fit == FIT_N9
    assert np.isnan(t.pos_err_mm[kept]).all()
    np.testing.assert_array_equal(t.xyz_mm[kept], n9.xyz_mm[kept])
    np.testing.assert_array_equal(t.i[kept], n9.i[kept])


def test_surface_map_is_exact_on_a_quadratic_surface_with_missing_taxels():
    taxels = grid_taxels(rows=5, cols=5)
    i, j = taxels.i.astype(float), taxels.j.astype(float)
    xyz = np.stack([16 * i, 12 * j, 0.3 * i**2 - 0.2 * i * j + 0.1 * j**2], axis=1)
    w = Window(taxels.i, taxels.j)
    centre = np.array([int(np.flatnonzero((taxels.i == 0) & (taxels.j == 0))[0])])
    win = w.taxels[centre]
    pos = xyz[np.where(win >= 0, win, 0)]
    n, k = win.shape
    coef, corr = np.empty((n, 6, 3)), np.empty((n, 5, 5, 3))
    scratch = [np.empty((n, k)) for _ in range(3)]
    prepare(
        np.zeros(n, np.int64),
        np.zeros(n, np.int64),
        centre,
        win,
        np.full((n, 9), -1, np.int64),
        np.zeros((1, len(taxels))),
        np.ones(len(taxels)),
        np.ones((n, len(taxels))),
        0.1,
        pos,
        w.basis,
        w.map_weight,
        w.map_low,
        w.map_ok,
        *scratch,
        coef,
        corr,
        np.empty(n, np.int64),
    )
    coef = coef[0]
    a, b = 0.4, 0.7  # grid offsets from the corner taxel
    want = [16 * a, 12 * b, 0.3 * a**2 - 0.2 * a * b + 0.1 * b**2]
    got = coef[0] + coef[1] * a + coef[2] * b + coef[3] * a * a + coef[4] * a * b + coef[5] * b * b
    assert got == pytest.approx(want, abs=1e-4)


def test_each_windows_surface_map_factor_is_that_of_its_own_taxels():
    """The factor a window keeps (`Window.map_low`) is the Cholesky factor of the weighted
    normal matrix of the taxels it has, ridge included, at the grid's corner (9 of 25
    cells), at its edge and inside."""
    taxels = grid_taxels(rows=6, cols=7)
    w = Window(taxels.i, taxels.j)
    for t in range(len(taxels)):
        have = w.taxels[t] >= 0
        b = w.basis[have]
        lhs = b.T @ (w.map_weight[have, None] * b)
        lhs[np.arange(1, 6), np.arange(1, 6)] += 1e-9 * np.trace(lhs)
        assert w.map_ok[t]
        low = w.map_low[t]
        np.testing.assert_array_equal(low, np.tril(low))
        np.testing.assert_allclose(low @ low.T, lhs, rtol=1e-12, atol=1e-12)
    assert {int(n) for n in (w.taxels >= 0).sum(axis=1)} == {9, 12, 15, 16, 20, 25}


def test_a_skin_without_a_footprint_law_is_one_error():
    taxels = grid_taxels()
    with pytest.raises(FrameError, match=r'method = "model".*footprint'):
        locate(
            taxels,
            [frame_of(taxels, np.array([40.0, 30.0, 0.0]))],
            heights=GapLaw(60, 2, np.nan, 1),
        )
    assert FootprintLaw.of(LAW).profile[0] == 1.0


def test_the_model_columns_round_trip_through_touches_csv_and_json(tmp_path):
    from fruitcli.sensing.live.loop import _shape
    from fruitcli.sensing.outputs.touch_csv import touch_bytes, touch_csv

    taxels = grid_taxels()
    frames = [frame_of(taxels, np.array([40.0, 30.0, 0.0]), noise=1.0, seed=s) for s in range(3)]
    t = locate(taxels, frames)
    with touch_csv(tmp_path / "touches.csv", ["c"], model=True) as out:
        out.write(touch_bytes(t, np.arange(3) / 100.0, model=True), len(t))
    with open(tmp_path / "touches.csv") as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    assert [r["fit"] for r in rows] == ["model"] * 3
    np.testing.assert_allclose([float(r["pos_err_mm"]) for r in rows], t.pos_err_mm, atol=1e-6)
    np.testing.assert_allclose([float(r["residual"]) for r in rows], t.residual, atol=1e-6)
    np.testing.assert_allclose([float(r["x_mm"]) for r in rows], t.xyz_mm[:, 0], atol=1e-6)
    line = json.loads(json.dumps(_shape(t, 0)))
    assert line["fit"] == "model"
    assert line["pos_err_mm"] == pytest.approx(t.pos_err_mm[0], abs=1e-4)
    # other methods keep their columns and JSON keys
    n9 = locate(taxels, frames, method="n9")
    assert "fit" not in _shape(n9, 0)
    assert touch_bytes(n9, np.arange(3) / 100.0).count(b"\n") == 3


def test_each_taxel_is_weighed_by_its_own_noise_in_the_baseline_frames():
    taxels = grid_taxels()
    std = np.where(np.arange(len(taxels)) % 3 == 0, 3.0, 1.0)
    rng = np.random.default_rng(4)
    values = BASE + rng.normal(0.0, std, (400, len(taxels)))
    rows, cols = taxel_cells(taxels, default_board(), "taxels")
    frames = np.full((400, 21, 12), BASE)
    frames[:, rows, cols] = values
    settings = Settings(method="model", baseline_frames=300)
    loc = Locator(taxels, default_board(), taxels.xyz_mm, settings, heights=LAW)
    loc.baseline(frames)
    assert loc.noise_counts == pytest.approx(std, rel=0.15)
    n9 = Locator(taxels, default_board(), taxels.xyz_mm, Settings(method="n9"), heights=LAW)
    n9.baseline(frames)
    assert n9.noise_counts is None  # only the model method weighs the taxels


def still_touch_frames(point, n=60, noise=2.0):
    """n frames of one still touch (a weak one: 40 counts at its point) under noise, as a
    board reports them (counts around the baseline, not clipped at it)."""
    taxels = grid_taxels()
    v = 40.0 * np.exp(-0.5 * (np.linalg.norm(taxels.xyz_mm - point, axis=1) / SIGMA_MM) ** 2)
    rows, cols = taxel_cells(taxels, default_board(), "taxels")
    frames = np.full((n, 21, 12), BASE)
    frames[:, rows, cols] += v + np.random.default_rng(7).normal(0.0, noise, (n, v.size))
    return taxels, np.round(frames)


def test_a_still_touch_fitted_over_several_frames_is_placed_better():
    point = np.array([36.0, 27.0, 0.0])
    taxels, frames = still_touch_frames(point)
    err = {}
    for k in (1, 8):
        loc = Locator(
            taxels,
            default_board(),
            taxels.xyz_mm,
            Settings(method="model", model_frames=k),
            heights=LAW,
        )
        t = loc.batch(np.asarray(frames), np.full(len(taxels), BASE))
        late = (t.frame >= 8) & (t.fit == FIT_MODEL)  # each fitted on 8 frames when k = 8
        err[k] = np.linalg.norm(t.xyz_mm[late] - point, axis=1)
        assert late.sum() > 40
    # the mean of 8 frames has a third of one frame's noise: the error falls with it
    assert err[8].mean() < 0.6 * err[1].mean()


def test_the_frames_before_a_chunk_are_read_again_and_the_stream_agrees():
    point = np.array([35.0, 28.0, 0.0])
    taxels, frames = still_touch_frames(point, n=30)
    settings = Settings(method="model", model_frames=4)
    loc = Locator(taxels, default_board(), taxels.xyz_mm, settings, heights=LAW)
    base = np.full(len(taxels), BASE)
    whole = loc.batch(np.asarray(frames), base)
    chunked = loc.batch(np.asarray(frames), base, size=7)
    np.testing.assert_array_equal(whole.frame, chunked.frame)
    np.testing.assert_allclose(whole.xyz_mm, chunked.xyz_mm, atol=1e-9)
    stream = Stream(loc, base)
    live = TouchTable.concat([stream.step(f) for f in np.asarray(frames, float)])
    np.testing.assert_allclose(live.xyz_mm, whole.xyz_mm, atol=1e-6)


def model_locator(taxels, frames):
    """The model method's locator on the taxels' own grid with the mean of `frames`."""
    settings = Settings(method="model", model_frames=frames)
    return Locator(taxels, default_board(), taxels.xyz_mm, settings, heights=LAW)


def test_frames_of_another_touch_before_are_left_out_of_the_mean():
    """A touch at one place for 10 frames, then one elsewhere: the second's first frame is
    fitted on itself alone (the frames before peak at another taxel of its window)."""
    taxels = grid_taxels()
    first, second = np.array([36.0, 27.0, 0.0]), np.array([52.0, 52.0, 0.0])
    frames = [frame_of(taxels, first, 60.0, noise=1.0, seed=s) for s in range(10)]
    frames += [frame_of(taxels, second, 60.0, noise=1.0, seed=s) for s in range(10, 14)]
    base = np.full(len(taxels), BASE)
    one, eight = (model_locator(taxels, k).batch(np.asarray(frames), base) for k in (1, 8))
    at = eight.frame == 10
    np.testing.assert_array_equal(eight.xyz_mm[at], one.xyz_mm[one.frame == 10])
    assert np.linalg.norm(eight.xyz_mm[at][0] - second) < 1.5
    # the first touch's 10th frame is the mean of 8 of its own frames: closer than one
    late = np.linalg.norm(eight.xyz_mm[eight.frame == 9][0] - first)
    assert late < 1.0


def test_the_mean_of_frames_stops_at_the_first_frame_without_the_touch():
    """A touch for 6 frames, a frame of noise alone (the finger lifted), then the touch
    again at the same place: its first frame back is fitted on itself alone, not on the
    frames before the gap, in a batch and live alike."""
    taxels = grid_taxels()
    point = np.array([36.0, 27.0, 0.0])
    frames = [frame_of(taxels, point, 60.0, noise=1.0, seed=s) for s in range(6)]
    frames += [frame_of(taxels, point, 0.0, noise=1.0, seed=6)]
    frames += [frame_of(taxels, point, 60.0, noise=1.0, seed=s) for s in range(7, 10)]
    base = np.full(len(taxels), BASE)
    one, eight = model_locator(taxels, 1), model_locator(taxels, 8)
    alone, mean = one.batch(np.asarray(frames), base), eight.batch(np.asarray(frames), base)
    back = 7  # the first frame after the gap
    np.testing.assert_array_equal(
        mean.xyz_mm[mean.frame == back], alone.xyz_mm[alone.frame == back]
    )
    # the frame after it is the mean of the two since the gap: not the frame alone
    assert not np.allclose(
        mean.xyz_mm[mean.frame == back + 1], alone.xyz_mm[alone.frame == back + 1]
    )
    stream = Stream(eight, base)
    live = TouchTable.concat([stream.step(f) for f in np.asarray(frames, float)])
    np.testing.assert_allclose(live.xyz_mm, mean.xyz_mm, atol=1e-6)
