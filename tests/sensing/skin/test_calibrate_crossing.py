"""The electrostatic skin in `fruit calibrate` and the printer emulator's board, on a
crossing table made by hand: the board's counts are the table's drop interpolated by
hand times counts per fF, and a bench recording made with a counts per fF and taxel gains
the calibration does not know gives them back."""

import numpy as np
import pytest

from fruitcli.errors import FrameError
from fruitcli.fsutil import write_csv
from fruitcli.scene import parse_scene
from fruitcli.sensing.frames.recording import Recording, write_npz
from fruitcli.sensing.inputs_stage import calibrate_inputs
from fruitcli.sensing.skin import forward
from fruitcli.sensing.skin.calibrate import run_calibrate
from fruitcli.sensing.skin.crossing_skin import CrossingSkin
from fruitcli.sensing.skin.virtual_bench import descend
from fruitcli.tables import read_taxels
from tests.sensing.skin.test_virtual_bench import pad_taxel_csv

GAPS = np.array([0.0, 1.0, 2.0, 4.0])
OFFSETS = np.array([-16.0, -8.0, -4.0, 0.0, 4.0, 8.0, 16.0])
AMPLITUDE_FF = {"small": 60.0, "medium": 150.0}  # -dC at contact over the crossing


def table(counts_per_ff: float = 0.5, gaps=GAPS) -> CrossingSkin:
    """A crossing table: -dC = A exp(-r^2 / 2 (8 mm)^2) exp(-gap / 1.5 mm) on its nodes."""
    gx, gy = np.meshgrid(OFFSETS, OFFSETS, indexing="ij")
    lateral = np.exp(-0.5 * (gx**2 + gy**2) / 64.0)
    gaps = np.asarray(gaps, float)
    decay = np.exp(-gaps / 1.5)[:, None, None]
    dc = np.stack([-a * decay * lateral for a in AMPLITUDE_FF.values()])
    arrays = {
        "c0_ff": np.array(800.0),
        "objects": np.array(list(AMPLITUDE_FF)),
        "gap_mm": gaps,
        "dx_mm": OFFSETS,
        "dy_mm": OFFSETS,
        "dc_ff": dc,
        "strain": np.array([0.0, 0.1]),
        "curvature_per_mm": np.array([0.0, 0.05]),
        "c_stretch_ff": np.array([[800.0, 799.0], [800.0, 801.0]]),
        "c_bend_ff": np.array([[800.0, 799.5], [800.0, 800.5]]),
    }
    summary = {
        "counts_per_ff": 0.25,  # overridden below: the summary's value is not used
        "objects": {n: {"footprint_sigma_mm": 8.0, "gap_decay_mm": 1.5} for n in AMPLITUDE_FF},
    }
    return CrossingSkin.from_table(arrays, summary, counts_per_ff)


def test_counts_per_ff_given_replaces_the_summarys():
    assert table(0.5).counts_per_ff == 0.5
    assert table(0.5).drop("small", 0.0, 0.0, 0.0) == pytest.approx(30.0, rel=1e-12)
    assert table(2.0).drop("medium", 0.0, 0.0, 0.0) == pytest.approx(300.0, rel=1e-12)


def test_the_printer_emulators_board_gives_the_tables_counts(tmp_path):
    """A tip 0.5 mm above the pad's top at model (3, -2): each taxel's counts are its
    baseline plus counts_per_ff times -dC interpolated (trilinear) between the table's
    nodes, by hand, times its gain; the noise is 0, so the frame rounds that."""
    from fruitcli.printer.placement import Placement
    from fruitcli.printer.skin_board import SkinBoard
    from fruitcli.scene import default_scene, load_skin_table
    from fruitcli.sensing.frames.board import taxel_cells

    taxels = read_taxels(pad_taxel_csv(tmp_path / "t.csv"))
    gains = 0.9 + 0.01 * np.arange(16)
    write_csv(tmp_path / "gains.csv", ["id", "gain"], ([k, g] for k, g in enumerate(gains)))
    (tmp_path / "skin.toml").write_text(
        '[skin]\nmodel = "electrostatic"\ncounts_per_ff = 0.5\ntaxel_gain = "gains.csv"\n'
        "noise_std_counts = 0.0\n"
    )
    params = forward.SkinParams.from_table(load_skin_table(tmp_path / "skin.toml"))
    board = default_scene().board
    tip = np.array([103.0, 98.0, 13.5])
    skin = SkinBoard(
        taxels, board, Placement([100.0, 100.0, 10.0]), lambda: tip, "small", 0, params, table()
    )

    def by_hand(dx, dy, gap):
        """The table's -dC (fF) linear in the gap, Catmull-Rom across the offsets (the
        end nodes repeated beyond), clamped to them."""
        n = len(OFFSETS)
        ex = np.exp(-0.5 * np.array([[x * x + y * y for y in OFFSETS] for x in OFFSETS]) / 64)
        at_gap = [
            np.interp(gap, GAPS, 60.0 * np.exp(-GAPS / 1.5) * ex[i, j])
            for i in range(n)
            for j in range(n)
        ]
        grid = np.reshape(at_gap, (n, n))
        along_y = [_catmull_rom(dy, OFFSETS, grid[i]) for i in range(n)]
        return _catmull_rom(dx, OFFSETS, np.array(along_y))

    off = np.array([3.0, -2.0]) - taxels.xyz_mm[:, :2]
    inside = np.all(np.abs(off) <= 16.0, axis=1)  # beyond the table: the Gaussian tail
    want = np.array([0.5 * by_hand(dx, dy, 0.5) for dx, dy in off])
    got = skin.mean_counts(tip) - skin.skin.baseline_counts
    np.testing.assert_allclose(got[inside], (gains * want)[inside], rtol=1e-9)
    assert inside.sum() == 4 and np.all(got[~inside] < got[inside].min())
    assert got[inside].max() > 10.0  # well above the rounding
    rows, cols = taxel_cells(taxels, board, "t.csv")
    frame = skin.frame(0)[rows, cols]
    assert np.all(np.abs(frame - (skin.skin.baseline_counts + gains * want))[inside] <= 0.5)


def test_the_board_refuses_an_object_the_table_lacks(tmp_path):
    from fruitcli.printer.placement import Placement
    from fruitcli.printer.skin_board import SkinBoard
    from fruitcli.scene import default_scene

    taxels = read_taxels(pad_taxel_csv(tmp_path / "t.csv"))
    with pytest.raises(FrameError, match="indenter: expected one of .*small, medium.*'finger'"):
        SkinBoard(
            taxels,
            default_scene().board,
            Placement([0, 0, 0]),
            lambda: None,
            "finger",
            response=table(),
        )


def hidden_bench(tmp_path, counts_per_ff: float, gains: np.ndarray, threshold=20.0):
    """The virtual bench's descent (`descend`) on the pad with the table at a counts per fF
    and taxel gains the calibration is not told; noise 0.4 counts."""
    taxels = forward.pad_taxels_mm(z_mm=3.0)
    params = forward.SkinParams(forward.default_footprints_mm(), noise_std_counts=0.4)
    skin = forward.make_skin(16, 1, params)
    skin = type(skin)(skin.baseline_counts, skin.noise_std_counts, skin.fab, gains, params)
    xy = np.concatenate([taxels[:, :2] + [3.0, 2.0], taxels[:, :2] - [2.0, 3.0]])
    contact = np.column_stack([xy, np.full(len(xy), 3.0)])
    rng = np.random.default_rng(4)
    run = descend(
        contact,
        taxels,
        skin.baseline_counts,
        skin,
        "small",
        0.1,
        20,
        threshold,
        rng,
        table(counts_per_ff),
    )
    frames = np.full((len(run.counts), 21, 12), 500, dtype=np.int64)
    frames[:, np.arange(16) // 4, np.arange(16) % 4] = run.counts
    meta = {"source": "bench", "indenter": "small", "step_mm": 0.1, "baseline_frames": 20}
    write_npz(
        tmp_path / "frames.npz",
        Recording(frames, np.arange(len(frames)) / 60.0, sample=run.sample, meta=meta),
    )
    write_csv(
        tmp_path / "truth.csv",
        ["sample", "x_mm", "y_mm", "z_mm"],
        ([int(k), *map(float, p)] for k, p in zip(run.truth_ids, run.truth_mm, strict=True)),
    )
    pad_taxel_csv(tmp_path / "t.csv")
    text = '[grid]\ntaxels = "t.csv"\n[skin]\nmodel = "electrostatic"\npermittivity = 3.1\n'
    (tmp_path / "s.toml").write_text(text)
    return parse_scene(text, tmp_path / "s.toml")


def test_calibrate_gives_back_the_counts_per_ff_and_the_gains(tmp_path):
    gains = np.random.default_rng(2).uniform(0.8, 1.2, 16)
    scene = hidden_bench(tmp_path, 0.7, gains)
    out = tmp_path / "cal"
    res = run_calibrate(
        calibrate_inputs(scene),
        tmp_path / "frames.npz",
        tmp_path / "truth.csv",
        tmp_path / "t.csv",
        out,
        response=table(0.2),  # the table in counts of another scale: only dC is used
    )
    measured = gains / gains.mean()  # every taxel is measured: gains normalized to mean 1
    assert res["skin_model"] == "electrostatic" and res["taxels_measured"] == 16
    assert res["counts_per_ff"] == pytest.approx(0.7 * gains.mean(), rel=0.01)
    cal = np.loadtxt(out / "gains.csv", delimiter=",", comments="#", skiprows=2)
    # activations of 20-30 counts at the threshold, rounded, with 0.4 counts of noise
    np.testing.assert_allclose(cal[:, 3], measured, rtol=0.03)
    assert res["noise_std_counts"] == pytest.approx(0.4, abs=0.1)
    from fruitcli.scene import load_skin_table

    skin = load_skin_table(out / "skin.toml")
    assert skin.model == "electrostatic" and skin.permittivity == 3.1
    assert skin.counts_per_ff == pytest.approx(res["counts_per_ff"], rel=1e-5)
    assert skin.gaps_mm == scene.skin.gaps_mm and skin.taxel_gain.name == "gains.csv"


def test_calibrate_refuses_an_indenter_the_table_lacks(tmp_path):
    scene = hidden_bench(tmp_path, 0.7, np.ones(16))
    with pytest.raises(FrameError, match="indenter: expected one of"):
        run_calibrate(
            calibrate_inputs(scene),
            tmp_path / "frames.npz",
            tmp_path / "truth.csv",
            tmp_path / "t.csv",
            tmp_path / "cal",
            indenter="finger",
            response=table(),
        )
    assert not (tmp_path / "cal").exists()


@pytest.mark.parametrize("gaps", [[0.0, 1.0, 2.0, 4.0], [0.0, 0.3, 0.7, 2.0, 5.0]])
def test_drop_and_activation_are_cubic_across_and_linear_along_the_gap(gaps):
    """Within the table's offsets and gaps the activation is counts_per_ff * -dC linear
    in the gap and Catmull-Rom across the offsets (the bench's fast path on a uniform
    gap grid changes nothing), and `activation` gives `drop`'s values."""
    t = table(0.5, gaps)
    rng = np.random.default_rng(5)
    dx, dy = rng.uniform(-16, 16, (2, 500))
    gap = rng.uniform(0, gaps[-1], 500)
    n = len(OFFSETS)
    for k, name in enumerate(t.objects):
        want = []
        for x, y, g in zip(dx, dy, gap, strict=True):
            grid = np.array(
                [
                    [np.interp(g, t.gap_mm, t.drop_counts[k, :, i, j]) for j in range(n)]
                    for i in range(n)
                ]
            )
            along_y = np.array([_catmull_rom(y, OFFSETS, grid[i]) for i in range(n)])
            want.append(_catmull_rom(x, OFFSETS, along_y))
        np.testing.assert_allclose(t.drop(name, dx, dy, gap), want, rtol=1e-12, atol=1e-12)
        taxels = np.column_stack([dx[:30], dy[:30], rng.uniform(-0.5, 0.5, 30)])
        gaps_g = np.linspace(3.0, -1.0, 17)
        off = np.array([0.5, -0.5, 0.2]) - taxels
        # a crossing as far from the indenter above the contact point as below it; a
        # press below contact raises every crossing alike
        press = np.exp(np.maximum(-gaps_g, 0.0) / t.press_decay_mm[k])[:, None]
        np.testing.assert_allclose(
            t.activation(name, [0.5, -0.5, 0.2], taxels, gaps_g),
            t.drop(
                name,
                off[None, :, 0],
                off[None, :, 1],
                np.maximum(gaps_g, 0.0)[:, None] + np.abs(off[None, :, 2]),
            )
            * press,
            rtol=1e-12,
        )


def test_the_benchs_descents_are_the_activation(monkeypatch):
    """`descent` (the lateral interpolation by blocks of contact points) gives
    `activation`'s counts, whatever the block size."""
    from fruitcli.sensing.skin import crossing_skin

    t = table(0.5, [0.0, 0.3, 0.7, 2.0, 5.0])
    rng = np.random.default_rng(6)
    taxels = np.column_stack([rng.uniform(-20, 20, (12, 2)), rng.uniform(-1, 1, 12)])
    contact = np.column_stack([rng.uniform(-20, 20, (7, 2)), rng.uniform(-1, 1, 7)])
    gaps = np.arange(5.0, -2.05, -0.1)
    for block in (1, 3 * 12 * 51, 10**6):
        monkeypatch.setattr(crossing_skin, "BLOCK_VALUES", block)
        descent = t.descent("medium", contact, taxels)
        for p in (0, 4, 5, 6, 2):
            np.testing.assert_allclose(
                descent(p, gaps), t.activation("medium", contact[p], taxels, gaps), rtol=1e-12
            )


def _catmull_rom(x: float, nodes: np.ndarray, values: np.ndarray) -> float:
    """Cubic convolution through `values` at `nodes` (Catmull-Rom's weights at the
    fraction of the interval holding x), x clamped to them."""
    x = min(max(x, nodes[0]), nodes[-1])
    i = min(max(int(np.searchsorted(nodes, x, side="right")) - 1, 0), len(nodes) - 2)
    t = (x - nodes[i]) / (nodes[i + 1] - nodes[i])
    p = [values[min(max(k, 0), len(nodes) - 1)] for k in range(i - 1, i + 3)]
    return 0.5 * (
        2 * p[1]
        + (p[2] - p[0]) * t
        + (2 * p[0] - 5 * p[1] + 4 * p[2] - p[3]) * t * t
        + (3 * p[1] - p[0] - 3 * p[2] + p[3]) * t**3
    )
