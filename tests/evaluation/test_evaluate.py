"""`fruit evaluate`: the paper's Table I row, file outputs, and every bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fruitcli.evaluation.metrics import reference_length, summarize
from tests.conftest import PAPER, ROOT


def test_paper_rest_row_is_reproduced(fruit, tmp_path):
    """Table I, 'Rest, small': mean 2.56 mm (1.7 %), std 1.28 mm (0.8 %) at 152 mm."""
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
        "--label",
        "Rest, small",
    )
    assert res.exit_code == 0, res.output
    s = json.loads((tmp_path / "ev" / "summary.json").read_text())
    assert s["n"] == 29 and s["dims"] == 3
    assert round(s["mean_mm"], 2) == 2.56 and round(s["std_mm"], 2) == 1.28
    assert round(s["mean_pct"], 1) == 1.7 and round(s["std_pct"], 1) == 0.8
    assert s["reference_length_mm"] == 152.0
    for name in ("errors.csv", "table.md", "table.csv", "top.png", "side.png"):
        assert (tmp_path / "ev" / name).exists(), name
    assert "2.56 mm (1.7 %)" in (tmp_path / "ev" / "table.md").read_text()


def test_default_reference_is_largest_truth_distance():
    pts = np.array([[0.0, 0, 0], [3, 4, 0], [1, 1, 1]])
    assert reference_length(pts) == pytest.approx(5.0)


def test_summary_uses_population_std():
    truth = np.zeros((4, 2))
    meas = np.array([[1.0, 0], [3, 0], [0, 1], [0, 3]])
    s = summarize(truth, meas, 100.0)
    assert s["mean_mm"] == pytest.approx(2.0)
    assert s["std_mm"] == pytest.approx(1.0)  # population, not sample (1.1547)
    assert s["mean_pct"] == pytest.approx(2.0)


def test_top_view_data_is_said_and_has_no_side_view(fruit, tmp_path):
    res = fruit(
        "evaluate",
        "--truth",
        PAPER / "paper_deformed_truth_xy.csv",
        "--measured",
        PAPER / "paper_deformed_measured_xy.csv",
        "--out",
        tmp_path / "d",
    )
    assert res.exit_code == 0, res.output
    assert "top view" in res.output
    assert not (tmp_path / "d" / "side.png").exists()
    errors = (tmp_path / "d" / "errors.csv").read_text()
    assert "top view (x, y) only" in errors and "error_z_mm" not in errors


def test_errors_csv_round_trip(fruit, tmp_path):
    fruit(
        "evaluate",
        "--truth",
        PAPER / "paper_rest_truth.csv",
        "--measured",
        PAPER / "paper_rest_measured.csv",
        "--out",
        tmp_path / "e",
    )
    from fruitcli.tables import read_table

    t = read_table(
        tmp_path / "e" / "errors.csv",
        ["sample", "error_mm", "error_x_mm", "error_y_mm", "error_z_mm"],
    )
    assert len(t["sample"]) == 29
    vec = np.column_stack([t["error_x_mm"], t["error_y_mm"], t["error_z_mm"]])
    np.testing.assert_allclose(np.linalg.norm(vec, axis=1), t["error_mm"], atol=2e-6)


def _csv(path, text):
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    "truth,measured,expected",
    [
        (
            "sample,x_mm,y_mm\n0,0,0\n1,1,1\n",
            "sample,x_mm,y_mm\n0,0,0\n2,1,1\n",
            "missing sample(s) 1 present in truth.csv; extra sample(s) 2",
        ),
        (
            "sample,x_mm,y_mm\n0,0,0\n1,1,1\n",
            "sample,x_mm,y_mm\n0,0,abc\n1,1,1\n",
            "measured.csv: row 2: column y_mm: not a number: 'abc'",
        ),
        (
            "sample,x_mm,y_mm\n0,0,0\n1,1,1\n",
            "sample,x_mm,y_mm\n0,0,nan\n1,1,1\n",
            "row 2: column y_mm: not finite",
        ),
        ("sample,x_mm,y_mm\n0,0,0\n1,1,1\n", "sample,x_mm\n0,0\n1,1\n", "missing column(s) y_mm"),
        ("sample,x_mm,y_mm\n0,0,0\n1,1,1\n", "", "measured.csv: empty file"),
        ("sample,x_mm,y_mm\n0,0,0\n1,1,1\n", "sample,x_mm,y_mm\n", "no data rows"),
        (
            "sample,x_mm,y_mm\n0,0,0\n0,1,1\n",
            "sample,x_mm,y_mm\n0,0,0\n1,1,1\n",
            "duplicate sample 0",
        ),
        (
            "sample,x_mm,y_mm\n0,0,0\n1,1,1\n",
            "sample,x_mm,y_mm\n0,0,0,9\n1,1,1\n",
            "row 2: expected 3 fields, got 4",
        ),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(fruit, tmp_path, truth, measured, expected):
    t = _csv(tmp_path / "truth.csv", truth)
    m = _csv(tmp_path / "measured.csv", measured)
    res = fruit("evaluate", "--truth", t, "--measured", m, "--out", tmp_path / "out")
    assert res.exit_code == 1
    assert expected in res.output
    assert "Traceback" not in res.output
    assert len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_bad_reference_length(fruit, tmp_path):
    res = fruit(
        "evaluate",
        "--truth",
        PAPER / "paper_rest_truth.csv",
        "--measured",
        PAPER / "paper_rest_measured.csv",
        "--out",
        tmp_path / "o",
        "--reference-length-mm",
        0,
    )
    assert res.exit_code == 1 and "expected a length > 0 mm" in res.output
    assert not (tmp_path / "o").exists()


def test_missing_file(fruit, tmp_path):
    res = fruit(
        "evaluate",
        "--truth",
        tmp_path / "nope.csv",
        "--measured",
        PAPER / "paper_rest_measured.csv",
        "--out",
        tmp_path / "o",
    )
    assert res.exit_code == 1 and "nope.csv: file not found" in res.output


def test_existing_outputs_survive_a_failed_run(fruit, tmp_path):
    out = tmp_path / "ev"
    fruit(
        "evaluate",
        "--truth",
        PAPER / "paper_rest_truth.csv",
        "--measured",
        PAPER / "paper_rest_measured.csv",
        "--out",
        out,
    )
    before = (out / "summary.json").read_text()
    bad = _csv(tmp_path / "bad.csv", "sample,x_mm,y_mm,z_mm\n0,1,2,x\n")
    res = fruit(
        "evaluate", "--truth", PAPER / "paper_rest_truth.csv", "--measured", bad, "--out", out
    )
    assert res.exit_code == 1
    assert (out / "summary.json").read_text() == before


def test_paper_table_scene(fruit, tmp_path):
    res = fruit("run", ROOT / "pipelines" / "paper-table.toml", "--out", tmp_path / "pt")
    assert res.exit_code == 0, res.output
    table = (tmp_path / "pt" / "evaluate" / "table.md").read_text()
    assert "| Rest, small | 29 | 3D | none | 2.56 mm (1.7 %) | 1.28 mm (0.8 %) |" in table
