"""`fruit demo` on the evaluation-only scene: report.md built from the run's files."""

from __future__ import annotations

import os

import pytest

from tests.conftest import ROOT


def test_demo_report_from_paper_table(fruit, tmp_path):
    res = fruit("demo", "--out", tmp_path, "--scenes", "paper-table")
    assert res.exit_code == 0, res.output
    report = (tmp_path / "report.md").read_text()
    # the figure data are registered already: both columns give the paper's own row
    assert (
        "| Rest, small (the paper's figure data) | 29 | already registered: 2.56 (1.7 %) "
        "/ 1.28 (0.8 %) | 2.56 (1.7 %) / 1.28 (0.8 %) | 2.6 (1.7 %) / 1.3 (0.8 %) |"
    ) in report
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
        "fruit-rest, paper-table, touchpad-4x4)"
    ]
    assert not any(tmp_path.iterdir())


def test_demo_in_an_unwritable_folder_is_one_line(fruit, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    res = fruit("demo", "--out", blocker / "out", "--scenes", "paper-table")
    assert res.exit_code == 1
    assert res.output.strip().splitlines() == [
        f"Error: --out {blocker}/out: {blocker} is a file, not a folder; choose another "
        "folder (nothing written)"
    ]
    read_only = tmp_path / "read-only"
    read_only.mkdir(mode=0o555)
    if os.access(read_only, os.W_OK):
        pytest.skip("running as root: a mode-555 folder is still writable")
    res = fruit("demo", "--out", read_only / "out", "--scenes", "paper-table")
    assert res.exit_code == 1 and len(res.output.strip().splitlines()) == 1
    assert "Permission denied" in res.output


def test_scenes_lists_each_bundled_scene_with_its_stages(fruit):
    res = fruit("scenes")
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert [line.split()[0] for line in lines] == [
        "fruit-breathing",
        "fruit-deformed",
        "fruit-rest",
        "paper-table",
        "touchpad-4x4",
    ]
    assert lines[3] == (
        "paper-table      The paper's Table I from its figure data (rest: 3D, "
        "deformed: top view only) [stages: evaluate]"
    )
    assert lines[4] == (
        "touchpad-4x4     The flat 4 x 4 touchpad of the paper's Figs. 7-9 "
        "[stages: pad-grid, tetra, simulate, sensitivity]"
    )


def test_scenes_copy_writes_an_editable_scene_with_its_data(fruit, tmp_path):
    res = fruit("scenes", "copy", "paper-table", tmp_path / "mine")
    assert res.exit_code == 0, res.output
    copied = sorted(
        p.relative_to(tmp_path / "mine").as_posix()
        for p in (tmp_path / "mine").rglob("*")
        if p.is_file()
    )
    assert copied == [
        "data/paper/paper_deformed_measured_xy.csv",
        "data/paper/paper_deformed_truth_xy.csv",
        "data/paper/paper_rest_measured.csv",
        "data/paper/paper_rest_truth.csv",
        "paper-table.toml",
    ]
    for name in copied[:-1]:
        assert (tmp_path / "mine" / name).read_bytes() == (ROOT / name).read_bytes()
    res = fruit("scenes", "copy", "fruit-rest", tmp_path / "fruit")
    text = (tmp_path / "fruit" / "fruit-rest.toml").read_text()
    assert 'artist = "fruit_artist.ply"' in text  # generated beside the scene on first use
    assert sorted(p.name for p in (tmp_path / "fruit").iterdir()) == ["fruit-rest.toml"]


def test_scenes_copy_refuses_a_non_empty_folder_and_unknown_names(fruit, tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    res = fruit("scenes", "copy", "paper-table", tmp_path)
    assert res.exit_code == 1
    assert res.output.strip().splitlines() == [
        f"Error: {tmp_path}: is not empty; give a new or empty folder (nothing written)"
    ]
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]
    res = fruit("scenes", "copy", "paper", tmp_path / "new")
    assert res.exit_code == 1 and "unknown scene 'paper' (bundled scenes: " in res.output
    assert not (tmp_path / "new").exists()


@pytest.mark.slow
def test_the_whole_demo_runs_every_bundled_scene_without_a_warning(tmp_path):
    """`fruit demo` as `make demo` runs it (all five bundled scenes into an empty folder):
    exit 0, no warning, a report with the observations, Table I's N9 and model rows and
    every picture it links; run again, every stage of every scene is reused."""
    import re
    import subprocess
    import sys

    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")

    def demo() -> str:
        done = subprocess.run(
            [sys.executable, "-c", "from fruitcli.cli.main import main; main()", "demo"],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=1800,
        )
        assert done.returncode == 0, done.stderr[-3000:]
        assert "warning" not in done.stderr.lower(), done.stderr
        return (tmp_path / "out" / "report.md").read_text()

    report = demo()
    assert "## The paper's observations against this run" in report
    for row in ("Rest, small", "Rest, medium", "Deformed, small", "Deformed, medium"):
        scene = "fruit-rest" if row.startswith("Rest") else "fruit-deformed"
        assert f"| {row} (ours: {scene}) |" in report
        model = rf"\| {row} \(ours: {scene}, model, "
        placed = r"\d+ % placed by the fit\) \|"
        assert re.search(model + r"the frame at the threshold, " + placed, report)
        assert re.search(
            model + r"mean of \d+ frames, chosen on the calibration run, " + placed, report
        )
    for picture in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report):
        assert (tmp_path / "out" / picture).is_file(), picture
    stages = re.findall(r"^\| ([a-z0-9-]+) \| [0-9.]+ \| (\d+) \| (\d+) \|$", report, re.M)
    assert [name for name, _, _ in stages] == [
        "paper-table",
        "fruit-rest",
        "fruit-deformed",
        "fruit-breathing",
        "touchpad-4x4",
    ]
    again = demo()
    rerun = re.findall(r"^\| ([a-z0-9-]+) \| [0-9.]+ \| (\d+) \| (\d+) \|$", again, re.M)
    assert [int(ran) for _, ran, _ in rerun] == [0] * 5, again
