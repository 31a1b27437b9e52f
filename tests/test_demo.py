"""`fruit demo` on the evaluation-only scene: report.md built from the run's files."""

from __future__ import annotations


def test_demo_report_from_paper_table(fruit, tmp_path):
    res = fruit("demo", "--out", tmp_path, "--scenes", "paper-table")
    assert res.exit_code == 0, res.output
    report = (tmp_path / "report.md").read_text()
    # the figure data are registered already: both columns give the paper's own row
    assert ("| Rest, small (the paper's figure data) | 29 | already registered: 2.56 (1.7 %) "
            "/ 1.28 (0.8 %) | 2.56 (1.7 %) / 1.28 (0.8 %) | 2.6 (1.7 %) / 1.3 (0.8 %) |") in report
    assert "evaluation only: measured points given" in report
    assert "paper-table/evaluate/rest-small/top.png" in report
    # a second run reuses the evaluation
    res = fruit("demo", "--out", tmp_path, "--scenes", "paper-table")
    assert "evaluate     reuse" in (tmp_path / "report.md").read_text()


def test_demo_unknown_scene_is_one_line(fruit, tmp_path):
    res = fruit("demo", "--out", tmp_path, "--scenes", "no-such-scene")
    assert res.exit_code == 1
    assert res.output.strip().splitlines() == [
        "Error: unknown scene 'no-such-scene' (bundled scenes: fruit-breathing, fruit-deformed, "
        "fruit-rest, paper-table, touchpad-4x4)"]
    assert not any(tmp_path.iterdir())
