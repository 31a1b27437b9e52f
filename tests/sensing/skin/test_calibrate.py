"""`fruit calibrate`: the skin's parameters recovered from a bench recording made with
parameters the calibration does not know, and mismatched inputs refused."""

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import FrameError
from fruitcli.fsutil import write_csv
from fruitcli.output_folder import MARKER
from fruitcli.sensing.frames.recording import Recording, write_npz
from fruitcli.sensing.skin import forward
from fruitcli.sensing.skin.calibrate import descent_gaps
from fruitcli.sensing.skin.virtual_bench import START_GAP_MM
from fruitcli.tables import read_table
from tests.sensing.skin.test_virtual_bench import pad_taxel_csv

HIDDEN = {"sigma_mm": 4.5, "contact_counts": 80.0, "gap_decay_mm": 2.0, "noise": 1.2}


def gaussian_footprint(d):
    return np.exp(-0.5 * (d / HIDDEN["sigma_mm"]) ** 2)


def hidden_bench(
    tmp_path, seed=0, step_mm=0.1, n_idle=10, threshold=20.0, footprint=gaussian_footprint,
    over=False, offsets=((3.0, 2.0), (-2.0, -3.0)),
):  # fmt: skip
    """A bench recording in the virtual bench's format (idle frames, then per sample the
    descent from 5 mm in step_mm steps up to the first frame over the threshold), made by
    the forward model's formula with HIDDEN parameters and taxel gains in 1 +- 20 %;
    `footprint` (d mm -> 1 at 0) the lateral law; samples at `offsets` (mm) from each
    taxel, and with `over` right over each taxel too."""
    rng = np.random.default_rng(seed)
    taxels = forward.pad_taxels_mm(z_mm=3.0)
    t = len(taxels)
    gains = rng.uniform(0.8, 1.2, t)
    base = np.round(500 + rng.uniform(-30, 30, t))
    xy = np.concatenate([taxels[:, :2] + np.array(off) for off in offsets])
    if over:
        xy = np.concatenate([xy, taxels[:, :2]])

    def noisy(mean):
        return np.round(mean + rng.normal(0, HIDDEN["noise"], mean.shape)).astype(np.int64)

    rows, samples = [noisy(np.broadcast_to(base, (n_idle, t)))], [np.full(n_idle, -1)]
    c0 = rows[0].mean(axis=0)
    for k, p in enumerate(xy):
        d = np.linalg.norm(taxels - [p[0], p[1], 3.0], axis=1)
        lateral = gains * HIDDEN["contact_counts"] * footprint(d)
        for gap in np.arange(START_GAP_MM, -2.0, -step_mm):
            c = noisy(base + lateral * np.exp(-gap / HIDDEN["gap_decay_mm"]))
            rows.append(c[None, :])
            hit = bool(np.any(c - c0 > threshold))
            samples.append(np.array([k if hit else -1]))
            if hit:
                break
    counts = np.concatenate(rows)
    frames = noisy(np.full((len(counts), 21, 12), 500.0))
    frames[:, np.arange(t) // 4, np.arange(t) % 4] = counts
    meta = {
        "source": "bench",
        "indenter": "small",
        "step_mm": step_mm,
        "baseline_frames": n_idle,
        "threshold_counts": threshold,
    }
    write_npz(
        tmp_path / "frames.npz",
        Recording(frames, np.arange(len(frames)) / 60.0, sample=np.concatenate(samples), meta=meta),
    )
    write_csv(
        tmp_path / "truth.csv",
        ["sample", "x_mm", "y_mm", "z_mm"],
        ([k, float(p[0]), float(p[1]), 3.0] for k, p in enumerate(xy)),
    )
    pad_taxel_csv(tmp_path / "t.csv")
    (tmp_path / "s.toml").write_text('[grid]\ntaxels = "t.csv"\n')
    return gains


def calibrate(tmp_path, truth="truth.csv"):
    return CliRunner().invoke(
        cli,
        [
            "calibrate",
            str(tmp_path / "frames.npz"),
            "--truth",
            str(tmp_path / truth),
            "--scene",
            str(tmp_path / "s.toml"),
            "--out",
            str(tmp_path / "cal"),
        ],
    )


def test_calibration_recovers_hidden_parameters_within_10_percent(tmp_path):
    import tomllib

    gains = hidden_bench(tmp_path)
    res = calibrate(tmp_path)
    assert res.exit_code == 0, res.output
    skin = tomllib.loads((tmp_path / "cal" / "skin.toml").read_text())["skin"]
    assert skin["footprint_sigma_mm"]["small"] == pytest.approx(HIDDEN["sigma_mm"], rel=0.1)
    assert skin["gap_decay_mm"] == pytest.approx(HIDDEN["gap_decay_mm"], rel=0.1)
    assert skin["noise_std_counts"] == pytest.approx(HIDDEN["noise"], rel=0.1)
    assert skin["taxel_gain"] == "gains.csv"
    got = read_table(tmp_path / "cal" / "gains.csv", ["id", "gain", "measured"])
    measured = got["measured"] == 1
    assert measured.all()  # every taxel has a sample 3.6 mm away
    scale = gains.mean()  # the gains' common factor belongs to contact_counts
    assert skin["contact_counts"] == pytest.approx(HIDDEN["contact_counts"] * scale, rel=0.1)
    assert got["gain"] == pytest.approx(gains / scale, rel=0.1)
    assert np.corrcoef(got["gain"], gains)[0, 1] > 0.9  # the gains themselves, not noise


def test_calibration_refuses_a_truth_file_that_does_not_match(tmp_path):
    hidden_bench(tmp_path)
    rows = read_table(tmp_path / "truth.csv", ["sample", "x_mm", "y_mm", "z_mm"])
    write_csv(
        tmp_path / "bad.csv",
        ["sample", "x_mm", "y_mm", "z_mm"],
        (
            [int(k) + 100, x, y, z]
            for k, x, y, z in zip(
                rows["sample"], rows["x_mm"], rows["y_mm"], rows["z_mm"], strict=True
            )
        ),
    )
    res = calibrate(tmp_path, "bad.csv")
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert "bad.csv: does not match the recording: samples 100, 101, 102" in res.output
    assert not (tmp_path / "cal").exists()


def test_descent_gaps_of_a_printer_bench_recording():
    """Printer-bench frames: the gap is the tip's z less the model origin's and the
    contact's; virtual-bench frames: 5 mm less j steps."""
    sample = np.array([-1, -1, -1, -1, 0, -1, 1])
    tip_z = np.array([30.0, 30.0, 12.0, 11.9, 11.8, 13.0, 12.9])
    rec = Recording(
        np.zeros((7, 2, 2), np.int64),
        np.arange(7.0),
        sample=sample,
        meta={"model_origin_mm": [100.0, 100.0, 5.0], "step_mm": 0.1},
        printer_mm=np.column_stack([np.zeros(7), np.zeros(7), tip_z]),
    )
    frames, samples, gaps = descent_gaps(rec, {0: 3.0, 1: 4.0}, 2, "r.npz")
    assert frames.tolist() == [2, 3, 4, 5, 6] and samples.tolist() == [0, 0, 0, 1, 1]
    assert gaps == pytest.approx([4.0, 3.9, 3.8, 4.0, 3.9])
    rec.printer_mm = None
    _, _, gaps = descent_gaps(rec, {0: 3.0, 1: 4.0}, 2, "r.npz")
    assert gaps == pytest.approx([5.0, 4.9, 4.8, 5.0, 4.9])
    rec.meta["start_gap_mm"] = {"1": 10.0}  # the second descent started higher
    _, _, gaps = descent_gaps(rec, {0: 3.0, 1: 4.0}, 2, "r.npz")
    assert gaps == pytest.approx([5.0, 4.9, 4.8, 10.0, 9.9])
    rec.meta["start_gap_mm"] = [10.0]
    with pytest.raises(FrameError, match=r"r.npz: meta start_gap_mm: expected a table"):
        descent_gaps(rec, {0: 3.0, 1: 4.0}, 2, "r.npz")


HIDDEN_SKIN = """
[skin]
footprint_sigma_mm = { small = 4.5 }
contact_counts = 80.0
gap_decay_mm = 2.0
gain_spread = 0.2
noise_std_counts = 1.2
"""


def virtual_bench_scene(tmp_path, skin=HIDDEN_SKIN):
    """The 4 x 4 pad on the virtual bench (`fruit bench`): 36 samples over the taxels,
    50 idle frames, the [skin] given."""
    pad_taxel_csv(tmp_path / "t.csv")
    c = np.linspace(-21.0, 21.0, 6)
    write_csv(
        tmp_path / "samples.csv",
        ["sample", "x_mm", "y_mm"],
        ([n, float(x), float(y)] for n, (x, y) in enumerate((x, y) for x in c for y in c)),
    )
    (tmp_path / "s.toml").write_text(
        '[grid]\ntaxels = "t.csv"\nspacing_x_mm = 16.0\nspacing_y_mm = 16.0\n'
        '[bench]\nindenters = ["small"]\nsamples = "samples.csv"\nbaseline_frames = 50\n'
        "seed = 4\n" + skin
    )
    return tmp_path / "s.toml"


def bench_and_calibrate(tmp_path, name, extra=()):
    runner = CliRunner()
    res = runner.invoke(
        cli, ["bench", str(tmp_path / "s.toml"), "--out", str(tmp_path / name), *extra]
    )
    assert res.exit_code == 0, res.output
    rec = tmp_path / name / "small"
    res = runner.invoke(
        cli,
        [
            "calibrate",
            str(rec / "frames.npz"),
            "--truth",
            str(rec / "truth.csv"),
            "--scene",
            str(tmp_path / "s.toml"),
            "--out",
            str(tmp_path / f"cal-{name}"),
        ],
    )
    assert res.exit_code == 0, res.output
    return tmp_path / f"cal-{name}"


def assert_hidden_skin(cal, gains):
    """skin.toml's [skin] as a scene's, and its parameters within 10 % of the hidden ones."""
    from fruitcli.scene import load_skin_table

    table = load_skin_table(cal / "skin.toml")  # readable as a scene's [skin]
    p = forward.SkinParams.from_table(table)
    assert p.footprint_sigma_mm["small"] == pytest.approx(4.5, rel=0.1)
    assert p.gap_decay_mm == pytest.approx(2.0, rel=0.1)
    assert p.noise_std_counts == pytest.approx(1.2, rel=0.1)
    scale = gains.mean()
    assert p.contact_counts == pytest.approx(80.0 * scale, rel=0.1)
    got = forward.load_taxel_gains(p.taxel_gain, np.arange(16))
    assert got == pytest.approx(gains / scale, rel=0.1)
    assert np.corrcoef(got, gains)[0, 1] > 0.9
    return p


def test_a_virtual_bench_with_a_hidden_skin_calibrates_back_and_replays(tmp_path):
    """`fruit bench` with hidden [skin] parameters, `fruit calibrate` on its recording: the
    parameters within 10 %; `fruit bench --skin skin.toml` then replays with the calibrated
    skin (its gains from gains.csv), and calibrating that recording finds them again."""
    from fruitcli.scene import load_scene, load_skin_table

    virtual_bench_scene(tmp_path)
    hidden = forward.SkinParams.from_table(load_scene(tmp_path / "s.toml").skin)
    gains = forward.make_skin(16, 4, hidden).gain
    assert gains.std() > 0.05  # the hidden skin is not uniform
    cal = bench_and_calibrate(tmp_path, "hidden")
    p = assert_hidden_skin(cal, gains)
    skin = forward.make_skin(16, 4, p, np.arange(16))
    assert np.array_equal(skin.gain, forward.load_taxel_gains(cal / "gains.csv", np.arange(16)))
    again = bench_and_calibrate(tmp_path, "replayed", ["--skin", str(cal / "skin.toml")])
    assert_hidden_skin(again, gains)
    # the replay's skin is the file's: half its contact counts, half the calibrated ones
    text = (cal / "skin.toml").read_text()
    half = text.replace(
        f"contact_counts = {p.contact_counts:.4f}", f"contact_counts = {p.contact_counts / 2:.4f}"
    )
    assert half != text
    (cal / "half.toml").write_text(half)
    weak = bench_and_calibrate(tmp_path, "half", ["--skin", str(cal / "half.toml")])
    q = forward.SkinParams.from_table(load_skin_table(weak / "skin.toml"))
    assert q.contact_counts == pytest.approx(p.contact_counts / 2, rel=0.1)
    meta = read_table(cal / "gains.csv", ["id", "gain"])
    assert meta["id"].tolist() == list(range(16))


def test_a_scene_skin_with_measured_gains(tmp_path):
    """[skin].taxel_gain in a scene: the virtual bench's gains are the file's; a taxel
    missing from it, or a drawn spread with it, is one line."""
    from fruitcli.errors import FrameError, SceneError
    from fruitcli.scene import load_scene
    from fruitcli.tables import read_taxels

    write_csv(tmp_path / "g.csv", ["id", "gain"], ([k, 1.0 + 0.01 * k] for k in range(16)))
    path = virtual_bench_scene(tmp_path, '[skin]\ntaxel_gain = "g.csv"\n')
    scene = load_scene(path)
    ids = read_taxels(tmp_path / "t.csv").ids
    skin = forward.make_skin(16, 0, forward.SkinParams.from_table(scene.skin), ids[::-1])
    np.testing.assert_allclose(skin.gain, 1.0 + 0.01 * np.arange(16)[::-1])
    write_csv(tmp_path / "g.csv", ["id", "gain"], ([k, 1.0] for k in range(15)))
    res = CliRunner().invoke(cli, ["bench", str(path), "--out", str(tmp_path / "b")])
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert "g.csv: no gain for taxel(s) 15 (1 of 16 taxels missing" in res.output
    with pytest.raises(FrameError, match="taxel 3: gain expected > 0"):
        write_csv(tmp_path / "g.csv", ["id", "gain"], ([k, float(k != 3)] for k in range(16)))
        forward.load_taxel_gains(tmp_path / "g.csv", ids)
    virtual_bench_scene(tmp_path, '[skin]\ntaxel_gain = "g.csv"\ngain_spread = 0.1\n')
    with pytest.raises(SceneError, match=r"\[skin\].gain_spread: expected 0 with taxel_gain"):
        load_scene(path)
    virtual_bench_scene(tmp_path)
    (tmp_path / "bad.toml").write_text("[skin]\ncontact_counts = 70.0\n[bench]\nseed = 1\n")
    res = CliRunner().invoke(
        cli,
        ["bench", str(path), "--skin", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "b")],
    )
    assert (
        res.exit_code == 1 and "bad.toml: expected only a [skin] table, found [bench]" in res.output
    ), res.output


def test_the_printer_emulators_skin_board_uses_the_skin_table(tmp_path):
    """The emulated board under the printer's tip answers with the [skin] it is given
    (calibrated gains, footprint, counts at contact, gap decay), in closed form."""
    from fruitcli.printer.placement import Placement
    from fruitcli.printer.skin_board import SkinBoard
    from fruitcli.scene import default_scene
    from fruitcli.tables import read_taxels

    taxels = read_taxels(pad_taxel_csv(tmp_path / "t.csv"))
    write_csv(tmp_path / "gains.csv", ["id", "gain"], ([k, 0.9 + 0.01 * k] for k in range(16)))
    (tmp_path / "skin.toml").write_text(
        "[skin]\nfootprint_sigma_mm = { small = 5.0 }\ncontact_counts = 70.0\n"
        'gap_decay_mm = 1.5\ntaxel_gain = "gains.csv"\nnoise_std_counts = 1.0\n'
    )
    from fruitcli.scene import load_skin_table

    p = forward.SkinParams.from_table(load_skin_table(tmp_path / "skin.toml"))
    board = default_scene().board
    place = Placement([100.0, 100.0, 10.0])
    tip = np.array([103.0, 98.0, 14.0])  # over model (3, -2), 1 mm above the pad's top
    skin = SkinBoard(taxels, board, place, lambda: tip, params=p)
    d = np.linalg.norm(taxels.xyz_mm - [3.0, -2.0, 3.0], axis=1)
    want = skin.skin.baseline_counts + (0.9 + 0.01 * np.arange(16)) * 70.0 * np.exp(
        -0.5 * (d / 5.0) ** 2
    ) * np.exp(-1.0 / 1.5)
    np.testing.assert_allclose(skin.mean_counts(tip), want, rtol=1e-12)
    assert np.all(skin.skin.noise_std_counts == 1.0)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"sample": None}, "frames.npz: no 'sample' key: not a bench recording"),
        (
            {"meta": {"indenter": "small", "baseline_frames": 10}},
            "frames.npz: meta has no step_mm (virtual bench) and no printer_mm",
        ),
        ({"sample_all": -1}, "samples 0, 1, 2, 3, 4 have no frame in"),
        (
            {"meta": {"step_mm": 0.1, "baseline_frames": 10}},
            "frames.npz: meta names no indenter: give --indenter",
        ),
        (
            {"meta": {"step_mm": 0.1, "indenter": "small", "baseline_frames": 100000}},
            "frames.npz: 100000 idle frames (meta baseline_frames): expected 2 ..",
        ),
    ],
)
def test_a_recording_without_what_calibration_needs_is_one_line(tmp_path, change, message):
    """A recording that lacks the frames (or the facts about them) a calibration needs:
    one line naming the file, exit code 1, an earlier calibration's files kept."""
    from fruitcli.sensing.frames.recording import read_npz

    hidden_bench(tmp_path)
    rec = read_npz(tmp_path / "frames.npz")
    sample = rec.sample
    if "sample_all" in change:
        sample = np.full_like(sample, change["sample_all"])
    if "sample" in change:
        sample = change["sample"]
    write_npz(
        tmp_path / "frames.npz",
        Recording(rec.frames, rec.t_s, sample=sample, meta=change.get("meta", rec.meta)),
    )
    (tmp_path / "cal").mkdir()
    (tmp_path / "cal" / MARKER).write_text("{}\n")  # the folder of an earlier run
    (tmp_path / "cal" / "skin.toml").write_text("kept\n")
    res = calibrate(tmp_path)
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert message in res.output and "Traceback" not in res.output
    assert sorted(p.name for p in (tmp_path / "cal").iterdir()) == [MARKER, "skin.toml"]
    assert (tmp_path / "cal" / "skin.toml").read_text() == "kept\n"


def test_calibrate_without_taxels_is_one_line(tmp_path):
    """A scene with no taxels (no tracks, no [grid].taxels) and no --taxels: one line
    naming the scene and what to give, exit 1, nothing written."""
    from tests.sensing.skin.test_virtual_bench import PAD_SCENE

    (tmp_path / "pad.toml").write_text(PAD_SCENE)
    (tmp_path / "frames.npz").write_bytes(b"")
    (tmp_path / "truth.csv").write_text("sample,x_mm,y_mm,z_mm\n")
    res = CliRunner().invoke(
        cli,
        ["calibrate", str(tmp_path / "frames.npz"), "--truth", str(tmp_path / "truth.csv"),
         "--scene", str(tmp_path / "pad.toml"), "--out", str(tmp_path / "skin")],
    )  # fmt: skip
    assert res.exit_code == 1
    assert res.output.strip().endswith("pad.toml: no taxels: give --taxels or [grid].taxels")
    assert len(res.output.strip().splitlines()) == 1 and not (tmp_path / "skin").exists()


def heavy_footprint(d):
    """A footprint with heavier tails than the Gaussian calibrate fits."""
    return 1.0 / (1.0 + (d / 8.0) ** 2) ** 1.5


@pytest.mark.parametrize("over", [False, True])
def test_gains_from_samples_over_the_taxels(tmp_path, over):
    """A board whose footprint is not the Gaussian calibrate fits, sampled half a pitch
    off its taxels: with a sample right over each taxel too, the gains come from those
    (calibration.json counts them) and are the board's within 4 % (the noise's share);
    without, none is counted."""
    import json

    half = ((8.0, 8.0), (-8.0, -8.0))  # half a pitch off the taxels, as fruit study's run
    gains = hidden_bench(tmp_path, footprint=heavy_footprint, over=over, offsets=half)
    res = calibrate(tmp_path)
    assert res.exit_code == 0, res.output
    summary = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    assert summary["gains_over_taxels"] == (16 if over else 0)
    if over:
        got = read_table(tmp_path / "cal" / "gains.csv", ["id", "gain"])["gain"]
        assert np.sqrt(np.mean((got / (gains / gains.mean()) - 1.0) ** 2)) < 0.04
