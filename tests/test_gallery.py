"""docs/gallery.py: its readers, and when it runs the demo (the drawing itself is looked at,
not tested)."""

from __future__ import annotations

import subprocess

import numpy as np

from tests.test_docs import DOCS, load

gallery = load(DOCS / "gallery.py", "docs_gallery")


def test_tracks_come_back_in_point_order_per_track(tmp_path):
    path = tmp_path / "tracks.csv"
    path.write_text(
        "# comment\n# another\ntrack,axis,index,point,x_mm,y_mm,z_mm\n"
        "0,x,0,1,1.0,2.0,3.0\n1,y,0,0,-1.0,0.0,0.5\n0,x,0,0,0.0,2.0,3.5\n0,x,0,2,2.0,2.0,2.5\n"
    )
    a, b = gallery.tracks(path)
    np.testing.assert_array_equal(a, [[0.0, 2.0, 3.5], [1.0, 2.0, 3.0], [2.0, 2.0, 2.5]])
    np.testing.assert_array_equal(b, [[-1.0, 0.0, 0.5]])


def test_error_columns_read_by_prefix(tmp_path):
    path = tmp_path / "errors.csv"
    path.write_text(
        "# units: mm\nsample,truth_x_mm,truth_y_mm,truth_z_mm,measured_x_mm,measured_y_mm,"
        "measured_z_mm\n0,1,2,3,4,5,6\n"
    )
    rows = gallery.read_rows(path)
    np.testing.assert_array_equal(gallery.xyz(rows, "truth_"), [[1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(gallery.xyz(rows, "measured_"), [[4.0, 5.0, 6.0]])


def test_an_earlier_demo_lacking_a_file_is_one_line(tmp_path, monkeypatch, capsys):
    for name in gallery.NEEDS[1:]:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("")

    def no_run(*args, **kwargs):
        raise AssertionError("the demo ran")

    monkeypatch.setattr(gallery.subprocess, "run", no_run)
    into = tmp_path / "pages"
    assert gallery.main(["--demo", str(tmp_path), "--into", str(into)]) == 1
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith(f"Error: gallery: {tmp_path / gallery.NEEDS[0]}: not there")
    assert not into.exists()


def test_a_failed_demo_is_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys):
    calls = []

    def failing(cmd, check):
        calls.append(cmd)
        raise subprocess.CalledProcessError(1, cmd)

    monkeypatch.setattr(gallery.subprocess, "run", failing)
    monkeypatch.setattr(gallery, "DEMO", tmp_path / "demo")
    into = tmp_path / "pages"
    assert gallery.main(["--into", str(into)]) == 1
    (cmd,) = calls
    assert cmd[-5:] == [
        "demo",
        "--scenes",
        "paper-table,fruit-rest,fruit-deformed",
        "--out",
        str(tmp_path / "demo"),
    ]
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"Error: gallery: fruit demo into {tmp_path / 'demo'} failed (exit code 1)"]
    assert not into.exists()
