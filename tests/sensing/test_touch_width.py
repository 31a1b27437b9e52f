"""The footprint's width from a recording's touches alone (`fruit calibrate` without
--truth): a board narrower or wider than the scene's skin gives its own width back, and
what cannot give a width is refused in one line."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import FrameError
from fruitcli.scene import load_scene, load_skin_table
from fruitcli.sensing.detection.model_fit import PROFILE_STEP_MM, FootprintLaw
from fruitcli.sensing.frames.recording import Recording, write_npz
from fruitcli.sensing.touch_width import MIN_TOUCHES, SCALES, _vertex, run_touch_width
from tests.sensing.skin import test_calibrate as tc

# samples off each of the pad's 16 taxels (mm), half a pitch (8 mm) and less: a narrow
# footprint is seen by four taxels only away from them
OFFSETS = ((3.0, 2.0), (-2.0, -3.0), (5.0, -4.0), (-6.0, 5.0), (8.0, 3.0), (5.0, 5.0), (3.0, -8.0))


def board(tmp_path, monkeypatch, sigma_mm, seed=0, offsets=OFFSETS):
    """A bench recording of a Gaussian board of footprint `sigma_mm` (gains +-20 %) in
    tmp_path, with the scene s.toml that assumes the default skin."""
    monkeypatch.setitem(tc.HIDDEN, "sigma_mm", sigma_mm)
    tc.hidden_bench(tmp_path, seed=seed, offsets=offsets)
    return load_scene(tmp_path / "s.toml")


SKIN_SIGMA_MM = 6.18  # the default skin's small footprint, which the scene assumes


@pytest.mark.parametrize("seed", [0, 1])
def test_a_board_wider_than_the_skin_gives_its_own_width(tmp_path, monkeypatch, seed):
    scene = board(tmp_path, monkeypatch, 8.0, seed)
    got = run_touch_width(scene, tmp_path / "frames.npz", tmp_path / "t.csv", tmp_path / "w")
    assert got["touches"] == len(OFFSETS) * 16
    assert got["footprint_sigma_mm"] == pytest.approx(8.0, rel=0.04)
    skin = load_skin_table(tmp_path / "w" / "skin.toml")
    assert skin.footprint_sigma_mm == {"small": pytest.approx(got["footprint_sigma_mm"], abs=1e-4)}
    assert skin.taxel_gain is None
    summary = json.loads((tmp_path / "w" / "calibration.json").read_text())
    assert summary["truth"] is None and len(summary["mean_reduced_chi2"]) == len(SCALES)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_narrower_board_moves_the_width_towards_its_own(tmp_path, monkeypatch, seed):
    # a footprint too wide differs from the board's only below the noise (the module's
    # docstring): the width found lies between the board's and the skin's, not beyond
    scene = board(tmp_path, monkeypatch, 5.0, seed)
    got = run_touch_width(scene, tmp_path / "frames.npz", tmp_path / "t.csv", tmp_path / "w")
    assert 0.95 * 5.0 < got["footprint_sigma_mm"] < 0.95 * SKIN_SIGMA_MM


def test_the_width_law_is_the_skin_law_widened():
    d = np.arange(0.0, 40.0, PROFILE_STEP_MM)
    law = FootprintLaw(np.exp(-0.5 * (d / 5.0) ** 2), 5.0, 1.0)
    wide = law.scaled(1.3, 0.01)
    assert wide.sigma_mm == pytest.approx(6.5) and wide.width_prior == 0.01
    np.testing.assert_allclose(wide.profile, np.exp(-0.5 * (d / 6.5) ** 2), atol=1e-4)


def test_the_parabola_vertex_refines_the_least_scale():
    x = np.array([0.9, 0.95, 1.0])
    assert _vertex(x, (x - 0.97) ** 2, 1) == pytest.approx(0.97)
    assert _vertex(x, -(x**2), 1) == 0.95  # opens downward: the sample itself


def test_too_few_touches_are_refused_naming_the_recording(tmp_path, monkeypatch):
    scene = board(tmp_path, monkeypatch, 5.0, offsets=((3.0, 2.0),))
    with np.load(tmp_path / "frames.npz") as f:  # the idle frames and the first samples
        sample = f["sample"]
        end = int(np.flatnonzero(sample == MIN_TOUCHES - 2)[0]) + 1
        meta = json.loads(str(f["meta"]))
        rec = Recording(f["frames"][:end], f["t_s"][:end], sample=sample[:end], meta=meta)
    frames = tmp_path / "few.npz"
    write_npz(frames, rec)
    with pytest.raises(FrameError, match=rf"few.npz: {MIN_TOUCHES - 1} touches .* at least"):
        run_touch_width(scene, frames, tmp_path / "t.csv", tmp_path / "w")
    assert not (tmp_path / "w").exists()


def test_a_width_at_the_edge_of_those_tried_is_refused(tmp_path, monkeypatch):
    scene = board(tmp_path, monkeypatch, 13.0)  # twice the skin's
    with pytest.raises(FrameError, match=r"edge of the widths tried .*footprint_sigma_mm"):
        run_touch_width(scene, tmp_path / "frames.npz", tmp_path / "t.csv", tmp_path / "w")
    assert not (tmp_path / "w").exists()


def test_the_crossing_table_skin_is_refused(tmp_path, monkeypatch):
    board(tmp_path, monkeypatch, 5.0)
    (tmp_path / "s.toml").write_text('[grid]\ntaxels = "t.csv"\n[skin]\nmodel = "electrostatic"\n')
    scene = load_scene(tmp_path / "s.toml")
    with pytest.raises(FrameError, match=r'\[skin\].model = "electrostatic".* --truth'):
        run_touch_width(scene, tmp_path / "frames.npz", tmp_path / "t.csv", tmp_path / "w")


def test_calibrate_without_truth_writes_the_width(tmp_path, monkeypatch):
    board(tmp_path, monkeypatch, 8.0)
    out = tmp_path / "cal"
    args = ["calibrate", str(tmp_path / "frames.npz"), "--scene", str(tmp_path / "s.toml")]
    res = CliRunner().invoke(cli, [*args, "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "footprint sigma " in res.output and "from 112 touches" in res.output
    assert load_skin_table(out / "skin.toml").footprint_sigma_mm["small"] == pytest.approx(
        8.0, rel=0.04
    )
    truth = ["--truth", str(tmp_path / "truth.csv"), "--states", str(tmp_path / "x.npz")]
    res = CliRunner().invoke(cli, [*args, *truth, "--out", str(tmp_path / "c2")])
    assert res.exit_code == 2 and "--states: only without --truth" in res.output
