"""Frame registration (`fruit evaluate --register`) and the per-row statistics."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fruitcli.errors import EvaluationError
from fruitcli.evaluation.metrics import bootstrap_ci, error_stats, match, read_points, summarize
from fruitcli.evaluation.register import register
from tests.conftest import PAPER

ROT = Rotation.from_rotvec(
    np.radians(23.0) * np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81])
).as_matrix()
SHIFT = np.array([110.0, -42.5, 7.25])


def paper_rest():
    _, t, m = match(
        read_points(PAPER / "paper_rest_truth.csv"), read_points(PAPER / "paper_rest_measured.csv")
    )
    return t, m


@pytest.mark.parametrize("method", ["rigid", "similarity"])
def test_a_known_rotation_and_translation_is_recovered_and_the_errors_unchanged(method):
    truth, meas = paper_rest()
    moved = meas @ ROT.T + SHIFT  # the same measurement in another frame (a printer's)
    a = register(truth, meas, method)
    b = register(truth, moved, method)
    np.testing.assert_allclose(b.apply(moved) - truth, a.apply(meas) - truth, atol=1e-9)
    # b undoes the frame change, then does what a did
    np.testing.assert_allclose(b.rotation, a.rotation @ ROT.T, atol=1e-12)
    np.testing.assert_allclose(b.scale, a.scale, rtol=1e-12)


def test_a_perfect_measurement_in_another_frame_registers_to_zero_error():
    truth, _ = paper_rest()
    moved = (truth - SHIFT) @ ROT  # truth = ROT @ moved + SHIFT
    t = register(truth, moved, "rigid")
    np.testing.assert_allclose(t.rotation, ROT, atol=1e-12)
    np.testing.assert_allclose(t.translation_mm, SHIFT, atol=1e-9)
    assert np.abs(t.apply(moved) - truth).max() < 1e-9
    assert t.rotation_deg == pytest.approx(23.0, abs=1e-9)
    shrunk = 0.97 * moved  # a cast piece 3 % smaller
    s = register(truth, shrunk, "similarity")
    assert s.scale == pytest.approx(1 / 0.97, rel=1e-12)
    assert np.abs(s.apply(shrunk) - truth).max() < 1e-9


def test_translation_of_zero_mean_errors_changes_nothing():
    truth, meas = paper_rest()
    zero_mean = meas - (meas - truth).mean(axis=0)  # exactly registered data
    t = register(truth, zero_mean, "translation")
    assert np.abs(t.translation_mm).max() < 1e-12
    np.testing.assert_allclose(t.apply(zero_mean), zero_mean, atol=1e-12)
    s = summarize(truth, zero_mean, 152.0, "translation")
    assert s["mean_mm"] == pytest.approx(s["compare"]["none"]["mean_mm"], abs=1e-12)


def test_the_papers_data_are_registered_already():
    """Their mean error vector is zero to 1e-6 mm: translation leaves the row as it is."""
    truth, meas = paper_rest()
    s = summarize(truth, meas, 152.0, "translation")
    assert np.abs(s["compare"]["none"]["bias_mm"]).max() < 1e-6
    assert abs(s["mean_mm"] - s["compare"]["none"]["mean_mm"]) < 1e-6
    assert round(s["mean_mm"], 2) == 2.56


def test_translation_removes_the_mean_error_vector():
    rng = np.random.default_rng(4)
    truth = rng.uniform(-50, 50, (30, 3))
    meas = truth + rng.normal(0, 1.0, truth.shape) + [2.0, -1.0, 0.5]
    s = summarize(truth, meas, 100.0, "translation")
    assert np.abs(s["bias_mm"]).max() < 1e-12
    np.testing.assert_allclose(
        s["compare"]["none"]["bias_mm"], (meas - truth).mean(axis=0), atol=1e-12
    )
    assert s["mean_mm"] < s["compare"]["none"]["mean_mm"]


def test_error_statistics_closed_form():
    err = np.array([[3.0, 4, 0], [0, 0, 1], [0, 2, 0], [1, 0, 0]])  # norms 5, 1, 2, 1
    s = error_stats(err)
    assert s["mean_mm"] == 2.25 and s["max_mm"] == 5.0 and s["median_mm"] == 1.5
    assert s["std_mm"] == pytest.approx(np.sqrt(((np.array([5, 1, 2, 1]) - 2.25) ** 2).mean()))
    assert s["rmse_mm"] == pytest.approx(np.sqrt(31 / 4))
    assert s["p95_mm"] == pytest.approx(np.percentile([5, 1, 2, 1], 95))
    assert s["bias_mm"] == [1.0, 1.5, 0.25]


def test_bootstrap_is_seeded_and_contains_the_mean():
    truth, meas = paper_rest()
    err = np.linalg.norm(meas - truth, axis=1)
    lo, hi = bootstrap_ci(err)
    assert (lo, hi) == bootstrap_ci(err)  # same data, same interval
    assert lo < err.mean() < hi
    assert (lo, hi) != bootstrap_ci(err, seed=1)
    assert hi - lo < 2 * 1.96 * err.std() / np.sqrt(len(err))  # narrower than 2 normal CIs
    wide = bootstrap_ci(err, level=0.99)
    assert wide[0] <= lo and wide[1] >= hi


def test_too_few_or_collinear_samples_are_refused():
    pts = np.array([[0.0, 0, 0], [1, 1, 1], [2, 0, 1]])
    with pytest.raises(
        EvaluationError, match="m.csv: register = rigid needs at least 3 matched sample"
    ):
        register(pts[:2], pts[:2], "rigid", "m.csv")
    line = np.array([[0.0, 0, 0], [1, 1, 1], [2, 2, 2], [3, 3, 3]])
    with pytest.raises(EvaluationError, match="lie on one line"):
        register(line, line + 1, "similarity", "m.csv")
    with pytest.raises(EvaluationError, match="translation needs at least 1"):
        register(np.zeros((0, 3)), np.zeros((0, 3)), "translation", "m.csv")
    with pytest.raises(
        EvaluationError, match="top-view .x, y. data support none and translation only"
    ):
        register(pts[:, :2], pts[:, :2], "rigid", "m.csv")


def _csv(path, rows, z=True):
    head = "sample,x_mm,y_mm" + (",z_mm" if z else "")
    path.write_text(head + "\n" + "\n".join(",".join(map(str, r)) for r in rows) + "\n")
    return path


def test_cli_register_writes_the_transform(fruit, tmp_path):
    res = fruit(
        "evaluate",
        "--truth",
        PAPER / "paper_rest_truth.csv",
        "--measured",
        PAPER / "paper_rest_measured.csv",
        "--out",
        tmp_path / "ev",
        "--reference-length-mm",
        152,
        "--register",
        "rigid",
    )
    assert res.exit_code == 0, res.output
    s = json.loads((tmp_path / "ev" / "summary.json").read_text())
    assert s["register"] == "rigid" and s["transform"]["method"] == "rigid"
    assert np.asarray(s["transform"]["rotation"]).shape == (3, 3)
    assert s["mean_mm"] <= s["compare"]["translation"]["mean_mm"] + 1e-12  # more freedom
    assert s["ci95_mean_mm"][0] < s["mean_mm"] < s["ci95_mean_mm"][1]
    table = (tmp_path / "ev" / "table.md").read_text()
    assert "rigid: translation (" in table and "rotation" in table
    errors = (tmp_path / "ev" / "errors.csv").read_text()
    assert "registered_error_mm" in errors and "error_mm" in errors


@pytest.mark.parametrize(
    "rows,z,method,expected",
    [
        (
            [(0, 0, 0, 0), (1, 1, 0, 0)],
            True,
            "rigid",
            "register = rigid needs at least 3 matched sample(s) not on one line, got 2",
        ),
        ([(0, 0, 0, 0), (1, 1, 1, 1), (2, 2, 2, 2)], True, "similarity", "lie on one line"),
        (
            [(0, 0, 0), (1, 1, 0), (2, 0, 1)],
            False,
            "rigid",
            "register = rigid needs 3D data (x, y, z); top-view (x, y) data support none and "
            "translation only",
        ),
    ],
)
def test_cli_bad_registration_is_one_line(fruit, tmp_path, rows, z, method, expected):
    t = _csv(tmp_path / "truth.csv", rows, z)
    m = _csv(tmp_path / "measured.csv", rows, z)
    res = fruit(
        "evaluate", "--truth", t, "--measured", m, "--out", tmp_path / "o", "--register", method
    )
    assert res.exit_code == 1
    assert expected in res.output and "measured.csv" in res.output
    assert len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_scene_register_key(fruit, tmp_path):
    from fruitcli.errors import SceneError
    from fruitcli.scene import parse_scene

    text = (
        f'[[evaluate]]\nlabel = "Rest, small"\ntruth = "{PAPER / "paper_rest_truth.csv"}"\n'
        f'measured = "{PAPER / "paper_rest_measured.csv"}"\nregister = "translation"\n'
    )
    (tmp_path / "s.toml").write_text(text)
    res = fruit("run", tmp_path / "s.toml", "--out", tmp_path / "out")
    assert res.exit_code == 0, res.output
    s = json.loads((tmp_path / "out" / "evaluate" / "summary.json").read_text())
    assert s["rest-small"]["register"] == "translation"
    with pytest.raises(
        SceneError,
        match=r"\[\[evaluate\]\] 'Rest, small'.register: expected "
        "one of none, translation, rigid, similarity",
    ):
        parse_scene(text.replace('"translation"', '"affine"'), tmp_path / "s.toml")


def test_large_samples_get_the_normal_interval():
    from fruitcli.evaluation.metrics import BOOTSTRAP_MAX_N

    rng = np.random.default_rng(2)
    err = rng.normal(0, 1.0, (BOOTSTRAP_MAX_N + 1, 3))
    s = error_stats(err)
    norm = np.linalg.norm(err, axis=1)
    half = 1.959964 * norm.std() / np.sqrt(len(norm))
    assert s["ci95_method"] == "normal"
    np.testing.assert_allclose(s["ci95_mean_mm"], [norm.mean() - half, norm.mean() + half])
    assert error_stats(err[:BOOTSTRAP_MAX_N])["ci95_method"] == "bootstrap"
