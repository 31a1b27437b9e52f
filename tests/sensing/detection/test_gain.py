"""Gain division in detection: activations divided by each taxel's calibrated
gain before the threshold, the maxima and the N9 weights; off by default."""

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.fsutil import write_csv
from fruitcli.sensing.detection.frames_to_touches import Locator, Stream
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.frames.board import default_board
from fruitcli.sensing.skin.forward import load_taxel_gains
from fruitcli.tables import read_taxels
from tests.sensing.detection.test_detect import BASE, frame_with, make_taxels
from tests.sensing.skin.test_calibrate import calibrate, hidden_bench


def locator(taxels, gain, **kw):
    return Locator(
        taxels, default_board(), taxels.xyz_mm, Settings(baseline_frames=1, **kw), gain=gain
    )


def gains_of(taxels, cells: dict) -> np.ndarray:
    """(T,) gains: 1, and cells' values at those (i, j)."""
    g = np.ones(len(taxels))
    for (i, j), v in cells.items():
        g[np.flatnonzero((taxels.i == i) & (taxels.j == j))[0]] = v
    return g


def n9_closed_form(v: dict, centre):
    """The N9 centroid (i, j) of activations v {(i, j): counts} around `centre`."""
    ci, cj = centre
    win = {(ci + a, cj + b): v.get((ci + a, cj + b), 0.0) for a in (-1, 0, 1) for b in (-1, 0, 1)}
    total = sum(win.values())
    return (
        sum(w * i for (i, _), w in win.items()) / total,
        sum(w * j for (_, j), w in win.items()) / total,
    )


@pytest.mark.parametrize("method", ["n9", "n9_floor", "peaks"])
def test_centroid_with_division_is_the_n9_centroid_of_the_divided_activations(method):
    tx = make_taxels()
    counts = {(2, 3): 60, (1, 3): 30, (2, 4): 24, (3, 2): 18, (1, 2): 9}
    gain = {(2, 3): 1.25, (1, 3): 0.75, (2, 4): 0.8, (3, 2): 1.5, (1, 2): 0.9}
    g = gains_of(tx, gain)
    floor = 4.0 if method == "n9_floor" else 0.0
    divided = {c: max(v / gain[c] - floor, 0.0) for c, v in counts.items()}
    want_i, want_j = n9_closed_form(divided, (2, 3))
    loc = locator(tx, g, method=method, noise_floor_counts=floor)
    frame = frame_with(counts)
    for t in (
        loc.batch(frame[None], np.full(len(tx), float(BASE))),
        Stream(loc, np.full(len(tx), float(BASE))).step(loc.values(frame[None])[0]),
    ):
        assert len(t) == 1
        assert (t.i[0], t.j[0]) == pytest.approx((want_i, want_j), abs=1e-12)
        assert t.peak[0] == pytest.approx(60 / 1.25)  # the peak is a divided activation
        w = np.array([divided.get((2 + a, 3 + b), 0.0) for a in (-1, 0, 1) for b in (-1, 0, 1)])
        cells = [(2 + a, 3 + b) for a in (-1, 0, 1) for b in (-1, 0, 1)]
        pts = np.array([tx.xyz_mm[(tx.i == i) & (tx.j == j)][0] for i, j in cells])
        assert t.xyz_mm[0] == pytest.approx(w @ pts / w.sum(), abs=1e-12)


def test_a_taxel_at_half_gain_is_detected_and_placed_as_at_full_gain():
    """The threshold applies after the division: a touch whose centre taxel has half the
    gain reads 20 counts there (not over the threshold 20) and is missed without the
    division; with it, it is found where and as strong as the same touch at full gain."""
    tx = make_taxels()
    base = np.full(len(tx), float(BASE))
    full = frame_with({(2, 3): 40, (1, 3): 20, (2, 4): 10})
    half = frame_with({(2, 3): 20, (1, 3): 20, (2, 4): 10})
    g = gains_of(tx, {(2, 3): 0.5})
    assert len(locator(tx, None).batch(half[None], base)) == 0
    want = locator(tx, None).batch(full[None], base)
    for method in ("n9", "peaks"):
        got = locator(tx, g, method=method).batch(half[None], base)
        assert (got.i[0], got.j[0], got.peak[0]) == (want.i[0], want.j[0], want.peak[0])
        assert np.array_equal(got.xyz_mm, want.xyz_mm)
    stream = Stream(locator(tx, g), base).step(locator(tx, g).values(half[None])[0])
    assert (stream.i[0], stream.j[0]) == pytest.approx((want.i[0], want.j[0]), abs=1e-15)


def test_division_by_gains_of_one_changes_nothing():
    rng = np.random.default_rng(2)
    tx = make_taxels()
    frames = BASE + rng.integers(-2, 60, (200, 21, 12))
    base = np.full(len(tx), float(BASE))
    a = locator(tx, None).batch(frames, base)
    b = locator(tx, np.ones(len(tx))).batch(frames, base)
    assert len(a) > 100
    for f in ("frame", "touch", "i", "j", "xyz_mm", "peak"):
        assert np.array_equal(getattr(a, f), getattr(b, f))


def locate(tmp_path, out, *extra):
    return CliRunner().invoke(
        cli,
        [
            "locate",
            str(tmp_path / "frames.npz"),
            "--taxels",
            str(tmp_path / "t.csv"),
            "--out",
            str(tmp_path / out),
            *extra,
        ],
    )


def test_round_trip_from_a_calibrate_run(tmp_path):
    """`fruit calibrate`'s gains.csv divides the activations of `fruit locate`, by the
    option or by the scene's [detection].divide_by_gain with [skin].taxel_gain: the same
    touches.csv, that of the batch path with those gains; without either, the paper's."""
    from fruitcli.sensing.frames.recording import read_npz

    hidden_bench(tmp_path)
    assert calibrate(tmp_path).exit_code == 0
    gains_csv = tmp_path / "cal" / "gains.csv"
    res = locate(tmp_path, "plain")
    assert res.exit_code == 0, res.output
    res = locate(tmp_path, "divided", "--divide-by-gain", str(gains_csv))
    assert res.exit_code == 0, res.output
    (tmp_path / "g.toml").write_text(
        '[detection]\ndivide_by_gain = true\n[skin]\ntaxel_gain = "cal/gains.csv"\n'
    )
    res = locate(tmp_path, "scene", "--scene", str(tmp_path / "g.toml"))
    assert res.exit_code == 0, res.output
    divided = (tmp_path / "divided" / "touches.csv").read_bytes()
    assert (tmp_path / "scene" / "touches.csv").read_bytes() == divided
    assert (tmp_path / "plain" / "touches.csv").read_bytes() != divided

    taxels = read_taxels(tmp_path / "t.csv")
    gain = load_taxel_gains(gains_csv, taxels.ids)
    assert gain.std() > 0.05  # the hidden skin's gains, ±20 %
    rec = read_npz(tmp_path / "frames.npz")
    loc = Locator(taxels, default_board(), taxels.xyz_mm, Settings(), gain=gain)
    t = loc.batch(rec.frames, loc.baseline(rec.frames))
    rows = divided.decode().splitlines()
    body = [r for r in rows if r and not r.startswith("#")][1:]
    assert len(body) == len(t)
    got = np.array([[float(x) for x in r.split(",")[:9]] for r in body])
    assert got[:, 0].tolist() == t.frame.tolist()
    np.testing.assert_allclose(got[:, 3:5], np.column_stack([t.i, t.j]), atol=1e-4)
    np.testing.assert_allclose(got[:, 8], t.peak, rtol=1e-6)


@pytest.mark.parametrize(
    "rows, message",
    [
        (None, "gains.csv: file not found"),
        (
            [[k, 1.0] for k in range(15)],
            "gains.csv: no gain for taxel(s) 15 (1 of 16 taxels missing",
        ),
        (
            [[k, 1.0] for k in range(17)],
            "gains.csv: id: gains for taxel(s) 16 that the taxel "
            "file does not have (17 gains for 16 taxels",
        ),
        ([[k, float(k != 5)] for k in range(16)], "gains.csv: taxel 5: gain expected > 0, got 0"),
        (
            [[k, -0.5 if k == 2 else 1.0] for k in range(16)],
            "gains.csv: taxel 2: gain expected > 0, got -0.5",
        ),
        (
            [[k, "nan" if k == 7 else 1.0] for k in range(16)],
            "gains.csv: row 9: column gain: not finite: 'nan'",
        ),
    ],
)
def test_bad_gain_files_are_one_line_and_write_nothing(tmp_path, rows, message):
    hidden_bench(tmp_path)
    if rows is not None:
        write_csv(tmp_path / "gains.csv", ["id", "gain"], rows)
    res = locate(tmp_path, "out", "--divide-by-gain", str(tmp_path / "gains.csv"))
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert message in res.output
    assert not (tmp_path / "out" / "touches.csv").exists()
    res = CliRunner().invoke(
        cli,
        [
            "live",
            str(tmp_path / "s.toml"),
            "--port",
            str(tmp_path / "no-port"),
            "--taxels",
            str(tmp_path / "t.csv"),
            "--divide-by-gain",
            str(tmp_path / "gains.csv"),
        ],
    )
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert message in res.output


def test_a_scene_that_divides_without_gains_is_refused(tmp_path):
    hidden_bench(tmp_path)
    (tmp_path / "g.toml").write_text("[detection]\ndivide_by_gain = true\n")
    res = locate(tmp_path, "out", "--scene", str(tmp_path / "g.toml"))
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert "g.toml: [detection].divide_by_gain: needs the gains, [skin].taxel_gain" in res.output
