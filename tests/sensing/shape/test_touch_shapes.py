"""Strength, size and hover height of touches from the skin model's own frames."""

import csv

import numpy as np
import pytest

from fruitcli.scene import default_scene
from fruitcli.sensing.detection.frames_to_touches import Locator
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.detection.touch_table import HOVER, KIND_NAMES, TOUCH, TouchTable
from fruitcli.sensing.frames.board import default_board
from fruitcli.sensing.outputs.touch_csv import TOUCH_HEADER, touch_bytes, touch_csv
from fruitcli.sensing.shape.touch_shape import frame_shapes, touch_shapes
from fruitcli.sensing.skin import forward
from fruitcli.sensing.skin.heights import GapLaw, gap_law
from fruitcli.tables import Taxels

PITCH_I, PITCH_J = 16.0, 12.0  # mm, the Fruit's two pitches


def grid_taxels() -> Taxels:
    i, j = np.divmod(np.arange(21 * 12), 12)
    return Taxels(np.arange(i.size), i, j, np.stack([PITCH_I * i, PITCH_J * j, 0.0 * i], axis=1))


def model_frame(
    taxels: Taxels, point_mm, gap_mm: float, base: float = 500.0, indenter: str = "small"
) -> np.ndarray:
    """Mean counts (21, 12) of the default skin with the indenter `gap_mm` above a point."""
    dist = np.linalg.norm(taxels.xyz_mm - np.asarray(point_mm, float), axis=1)
    v = forward.activation_counts(dist[None, :], np.array([gap_mm]), indenter)[0]
    return (base + v).reshape(21, 12)


def locate_frames(frames: np.ndarray, settings: Settings | None = None):
    settings = settings or Settings(threshold_counts=5.0)
    taxels = grid_taxels()
    loc = Locator(taxels, default_board(), taxels.xyz_mm, settings)
    return loc.batch(frames, np.full(len(taxels), 500.0))


@pytest.mark.parametrize("gap_mm", [0.0, 0.5, 1.0, 2.0, 3.0])
@pytest.mark.parametrize("point", [(80.0, 60.0), (84.0, 57.0), (75.0, 64.5)])
def test_height_from_a_model_frame_at_a_known_height(gap_mm, point):
    """Unrounded model counts: the gap law's height comes back to round-off, and the
    footprint's sigma as size (NaN when an axis' far neighbour is below MIN_COUNTS on
    both axes, as for a weak hover between taxels)."""
    frame = model_frame(grid_taxels(), (*point, 0.0), gap_mm)
    t = locate_frames(frame[None])
    assert len(t) == 1
    assert t.height_mm[0] == pytest.approx(gap_mm, abs=1e-9)
    assert t.strength[0] == pytest.approx(np.exp(-gap_mm / forward.GAP_DECAY_MM), rel=1e-9)
    sigma = forward.default_footprints_mm()["small"]
    if gap_mm <= 1.0:
        assert t.size_mm[0] == pytest.approx(sigma, rel=1e-9)
    else:
        assert np.isnan(t.size_mm[0]) or t.size_mm[0] == pytest.approx(sigma, rel=1e-9)


def test_height_from_integer_counts_within_the_model_resolution():
    """Counts rounded to integers, as the board gives them: within 3 of the reported
    1-sigma uncertainty (rounding: std 0.29 counts, below the skin's noise std)."""
    taxels = grid_taxels()
    for gap_mm in (0.0, 1.0, 2.0):
        frame = np.round(model_frame(taxels, (84.0, 57.0, 0.0), gap_mm))
        t = locate_frames(frame[None])
        assert 0 < t.height_err_mm[0] < 0.3
        assert abs(t.height_mm[0] - gap_mm) <= 3 * t.height_err_mm[0]


def test_firm_press_is_strength_above_one_and_height_zero():
    frame = model_frame(grid_taxels(), (80.0, 60.0, 0.0), -1.0)
    t = locate_frames(frame[None])
    assert t.strength[0] == pytest.approx(np.exp(0.5), rel=1e-9)
    assert t.height_mm[0] == 0.0


def test_shapes_use_the_skin_gains_and_report_uncertainty():
    """A taxel gain of 2 under the touch: the model expects twice the counts there."""
    di, dj = np.repeat(np.arange(-1, 2), 3), np.tile(np.arange(-1, 2), 3)
    pos9 = np.stack([PITCH_I * di, PITCH_J * dj, 0.0 * di], axis=1)[None]
    law = GapLaw(60.0, 2.0, 6.0, 1.5, gain=np.full(9, 2.0))
    d = np.linalg.norm(pos9[0], axis=1)
    v9 = (2.0 * 60.0 * np.exp(-0.5 * (d / 6.0) ** 2) * np.exp(-0.5))[None]
    sh = touch_shapes(v9, np.arange(9)[None], pos9, np.zeros((1, 3)), law)
    assert sh.height_mm[0] == pytest.approx(1.0, rel=1e-12)
    m = 2.0 * 60.0 * np.exp(-0.5 * (d / 6.0) ** 2)
    err_s = 1.5 / np.sqrt((m**2).sum())
    assert sh.height_err_mm[0] == pytest.approx(2.0 * err_s / np.exp(-0.5), rel=1e-12)


def test_gap_law_takes_the_skin_table_and_footprint():
    skin = (
        default_scene()
        .with_values(
            {
                "skin.footprint_sigma_mm": {"medium": 7.5},
                "skin.contact_counts": 80.0,
                "skin.gap_decay_mm": 1.5,
                "skin.noise_std_counts": 1.2,
            }
        )
        .skin
    )
    params = forward.SkinParams.from_table(skin)
    law = gap_law(params, footprint="medium")
    assert (law.contact, law.gap_decay_mm, law.sigma_mm, law.noise_std_counts) == (
        80.0,
        1.5,
        7.5,
        1.2,
    )


def test_touches_csv_round_trips_every_new_column(tmp_path):
    n = 4
    table = TouchTable.make(
        np.arange(n),
        np.array([0, 1, 1, 2]),
        np.linspace(1, 2, n),
        np.linspace(3, 4, n),
        np.arange(12.0).reshape(n, 3),
        np.array([25.0, 12.5, 30.0, 9.0]),
        np.array([0.0, 1.25, 0.0, 2.5]),
        np.array([0.01, 0.1, 0.02, 0.3]),
        np.array([1.2, 0.5, 1.0, 0.3]),
        np.array([6.1, np.nan, 7.0, 5.5]),
        np.array([TOUCH, HOVER, TOUCH, HOVER], np.int8),
    )
    path = tmp_path / "touches.csv"
    with touch_csv(path, ["test"]) as out:
        out.write(touch_bytes(table, np.arange(n) * 0.5), n)
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    rows = list(csv.DictReader(lines))
    assert list(rows[0]) == TOUCH_HEADER
    assert [r["kind"] for r in rows] == [KIND_NAMES[k] for k in table.kind]
    for name in ("height_mm", "height_err_mm", "strength", "size_mm", "peak"):
        got = np.array([float(r[name]) for r in rows])
        np.testing.assert_allclose(got, getattr(table, name), atol=5e-7)
    assert [int(r["touch"]) for r in rows] == table.touch.tolist()


class _PlainLaw(GapLaw):
    """The same law, through the generic (numpy) path of `touch_shapes`."""


def test_compiled_gap_law_shapes_equal_the_generic_path():
    """Noisy frames with touches anywhere, some hovering, at the board's edges too."""
    rng = np.random.default_rng(11)
    taxels = grid_taxels()
    frames = np.stack(
        [
            model_frame(
                taxels, (rng.uniform(-8, 330), rng.uniform(-6, 140), 0.0), rng.uniform(-0.5, 3.0)
            ).ravel()
            + rng.normal(0, 1.2, 252)
            for _ in range(300)
        ]
    )
    t = locate_frames(frames.reshape(-1, 21, 12))
    assert len(t) > 250
    law = GapLaw(60.0, 2.0, 6.2, 1.3, gain=rng.uniform(0.8, 1.2, 252))
    plain = _PlainLaw(60.0, 2.0, 6.2, 1.3, gain=law.gain)
    tax = np.arange(252).reshape(21, 12)
    ti, tj = np.rint(t.i).astype(int), np.rint(t.j).astype(int)
    di, dj = np.repeat(np.arange(-1, 2), 3), np.tile(np.arange(-1, 2), 3)
    ii, jj = ti[:, None] + di, tj[:, None] + dj
    inside = (ii >= 0) & (ii < 21) & (jj >= 0) & (jj < 12)
    tax9 = np.where(inside, tax[np.clip(ii, 0, 20), np.clip(jj, 0, 11)], -1)
    v = np.maximum(frames - 500.0, 0.0)
    v9 = v[t.frame[:, None], np.maximum(tax9, 0)] * inside
    pos9 = taxels.xyz_mm[np.maximum(tax9, 0)]
    a = touch_shapes(v9, tax9, pos9, t.xyz_mm, law)
    b = touch_shapes(v9, tax9, pos9, t.xyz_mm, plain)
    assert np.isnan(a.size_mm).any() and not np.isnan(a.size_mm).all()
    for name in ("strength", "size_mm", "height_mm", "height_err_mm"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-12, atol=1e-12)


def test_shapes_gathered_from_the_frames_equal_those_of_gathered_activations():
    """`frame_shapes` (the batch path: one compiled pass reading the frames) gives the
    values `touch_shapes` gives on the same activations gathered by numpy, to the bit:
    with and without gain division, positions by taxel or one (n, 9) block per touch,
    and through the generic path of another law."""
    rng = np.random.default_rng(12)
    taxels = grid_taxels()
    frames = np.stack(
        [
            model_frame(taxels, (rng.uniform(-8, 330), rng.uniform(-6, 140), 0.0), 0.3).ravel()
            + rng.normal(0, 1.2, 252)
            for _ in range(200)
        ]
    )
    counts = np.round(frames).astype(np.int64)
    t = locate_frames(counts.reshape(-1, 21, 12).astype(float))
    assert len(t) > 150
    n = len(t)
    tax9 = np.where(rng.random((n, 9)) < 0.1, -1, rng.integers(0, 252, (n, 9)))
    cell = rng.permutation(252)
    base = 500.0 + rng.normal(0, 0.3, 252)
    divide = rng.uniform(0.7, 1.3, 252)
    tax = np.maximum(tax9, 0)
    law = GapLaw(60.0, 2.0, 6.2, 1.3, gain=rng.uniform(0.8, 1.2, 252))
    for div in (None, divide):
        v9 = np.maximum(counts[t.frame[:, None], cell[tax]] - base[tax], 0.0) * (tax9 >= 0)
        if div is not None:
            v9 = v9 / div[tax]
        pos9 = taxels.xyz_mm[tax] + rng.normal(0, 0.5, (n, 9, 3))
        want = touch_shapes(v9, tax9, taxels.xyz_mm[tax], t.xyz_mm, law)
        got = frame_shapes(
            counts, t.frame, cell, base, div, tax9, taxels.xyz_mm, tax, t.xyz_mm, law
        )
        want9 = touch_shapes(v9, tax9, pos9, t.xyz_mm, law)
        rows = np.arange(n * 9).reshape(n, 9)
        got9 = frame_shapes(
            counts, t.frame, cell, base, div, tax9, pos9.reshape(-1, 3), rows, t.xyz_mm, law
        )
        with np.errstate(divide="ignore", invalid="ignore"):  # touches far from their taxels
            plain = _PlainLaw(60.0, 2.0, 6.2, 1.3, gain=law.gain)
            generic = frame_shapes(
                counts, t.frame, cell, base, div, tax9, taxels.xyz_mm, tax, t.xyz_mm, plain
            )
            want_generic = touch_shapes(v9, tax9, taxels.xyz_mm[tax], t.xyz_mm, plain)
        for name in ("strength", "size_mm", "height_mm", "height_err_mm"):
            np.testing.assert_array_equal(getattr(got, name), getattr(want, name))
            np.testing.assert_array_equal(getattr(got9, name), getattr(want9, name))
            np.testing.assert_array_equal(getattr(generic, name), getattr(want_generic, name))


def test_a_touch_without_taxels_near_its_centre_has_no_strength_or_height():
    law = GapLaw(60.0, 2.0, 6.2, 1.3)
    v9 = np.zeros((1, 9))
    v9[0, 4] = 40.0
    tax9 = np.full((1, 9), -1)
    tax9[0, 4] = 0
    pos9 = np.zeros((1, 9, 3))
    pos9[0, 4] = [1e4, 0, 0]  # far from the reported point: the footprint underflows
    sh = touch_shapes(v9, tax9, pos9, np.zeros((1, 3)), law)
    assert np.isnan([sh.strength[0], sh.height_mm[0], sh.height_err_mm[0]]).all()
