"""`fruit skin`: the crossing's outputs on a small cell, and bad inputs as one line naming
the scene key, exit 1, nothing written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fruitcli.output_folder import MARKER

SMALL_CELL = """
[grid]
spacing_x_mm = 6.0
spacing_y_mm = 5.0

[tracks]
cover_mm = 1.5
track_radius_mm = 0.6

[skin]
yarn_radius_mm = 0.4
insulation_mm = 0.1
gaps_mm = [0.0, 1.0]
"""


def _scene(tmp_path, text: str = SMALL_CELL):
    path = tmp_path / "cell.toml"
    path.write_text(text)
    return path


@pytest.mark.slow
def test_skin_writes_the_table_and_summary(tmp_path, fruit):
    out = tmp_path / "out"
    result = fruit("-q", "skin", _scene(tmp_path), "--out", out)
    assert result.exit_code == 0, result.output
    with np.load(out / "crossing.npz") as data:
        assert float(data["c0_ff"]) > 0
        assert list(data["objects"]) == ["small", "medium", "finger"]
        assert np.array_equal(data["gap_mm"], [0.0, 1.0])
        assert int(data["version"]) == 2
        assert np.allclose(data["dx_mm"], np.arange(-9.0, 9.1, 1.5))  # 1.5 pitches
        assert np.allclose(data["dy_mm"], np.arange(-7.5, 7.6, 1.25))
        dc = data["dc_ff"]
        assert dc.shape == (3, 2, 13, 13)
        assert np.all(dc < 0)  # a grounded object takes field from Rx
        assert np.allclose(dc, dc[:, :, ::-1, :]) and np.allclose(dc, dc[:, :, :, ::-1])
        assert np.all(np.abs(dc[:, 1]) < np.abs(dc[:, 0]))  # weaker further away
        assert np.all(np.abs(dc[:, 0, 6, 6]) >= 0.9 * np.abs(dc[:, 0]).max(axis=(1, 2)))
        assert data["c_stretch_ff"].shape == (2, len(data["strain"]))
        assert data["c_bend_ff"].shape == (2, len(data["curvature_per_mm"]))
        assert data["c_stretch_ff"][0, 0] == pytest.approx(float(data["c0_ff"]))
        assert list(data["deformations"]) == ["stretch_x", "stretch_y", "bend_x", "bend_y"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["c0_ff"] == pytest.approx(float(np.load(out / "crossing.npz")["c0_ff"]))
    fit = summary["counts_fit"]
    assert abs(fit["shift_ff"]) * summary["counts_per_ff"] == pytest.approx(10.0)
    for name in ("small", "medium", "finger"):
        obj = summary["objects"][name]
        assert obj["footprint_sigma_mm"] > 0 and obj["gap_decay_mm"] > 0
        assert obj["contact_counts"] == pytest.approx(
            -summary["counts_per_ff"] * obj["contact_dc_ff"]
        )
    assert summary["mesh_s"] > 0 and summary["solve_s"] > 0
    assert summary["inputs"]["yarn_radius_mm"] == 0.4


@pytest.mark.parametrize(
    "edit, key",
    [
        ("permittivity = 0.0", "[skin].permittivity"),
        ("permittivity = -2.8", "[skin].permittivity"),
        ("insulation_mm = 0.0", "[skin].insulation_mm"),
        ("gaps_mm = [0.5, 1.0]", "[skin].gaps_mm"),
        ("gaps_mm = [0.0, 1.0, 1.0]", "[skin].gaps_mm"),
        ("yarn_radius_mm = 2.6", "[skin].yarn_radius_mm"),
        ("yarn_radius_mm = 1.6", "[skin].yarn_radius_mm"),
        ("yarn_radius_mm = 0.74", "[skin].yarn_radius_mm"),
        ('model = "electrostatics"', "[skin].model"),
    ],
)
def test_bad_skin_inputs_are_one_line_naming_the_key(tmp_path, fruit, edit, key):
    """Permittivity <= 0, no insulation, a gap table not from contact or not increasing,
    a yarn wider than half the pitch (2.5 mm), than the cover (1.5 mm) or reaching the
    surface, an unknown model."""
    text = SMALL_CELL.replace("[skin]\n", f"[skin]\n{edit}\n")
    text = "\n".join(
        line
        for line in text.splitlines()
        if not (line.split("=")[0].strip() == edit.split("=")[0].strip() and line != edit)
    )
    out = tmp_path / "out"
    result = fruit("-q", "skin", _scene(tmp_path, text), "--out", out)
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and key in lines[0], result.output
    assert not out.exists()


def test_a_table_too_long_is_refused_with_its_estimate(tmp_path, fruit):
    """So many gaps on the Fruit's pitch that the table would take hours: one line naming
    [skin].gaps_mm with the estimate, nothing written."""
    gaps = [round(0.01 * k, 2) for k in range(1000)]
    text = (
        SMALL_CELL.replace("spacing_x_mm = 6.0", "spacing_x_mm = 16.0")
        .replace("spacing_y_mm = 5.0", "spacing_y_mm = 12.0")
        .replace("gaps_mm = [0.0, 1.0]", f"gaps_mm = {gaps}")
    )
    out = tmp_path / "out"
    result = fruit("-q", "skin", _scene(tmp_path, text), "--out", out)
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "[skin].gaps_mm" in lines[0] and "min" in lines[0], lines
    assert not out.exists()


def test_a_cell_too_large_is_refused_with_its_estimate(tmp_path, fruit):
    """A pitch whose cell would not fit in memory: one line naming the pitch's keys with
    the estimate, nothing written."""
    text = SMALL_CELL.replace("spacing_x_mm = 6.0", "spacing_x_mm = 400.0").replace(
        "spacing_y_mm = 5.0", "spacing_y_mm = 300.0"
    )
    out = tmp_path / "out"
    result = fruit("-q", "skin", _scene(tmp_path, text), "--out", out)
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "[grid].spacing_x_mm" in lines[0] and "GB" in lines[0]
    assert not out.exists()


@pytest.mark.parametrize("key", ["spacing_x_mm", "spacing_y_mm"])
def test_an_object_wider_than_the_cell_is_refused(tmp_path, fruit, key):
    """A pitch of 3.5 mm: the cell spans 2 pitches either side (14 mm), the finger is 16
    mm wide: one line naming the smaller pitch's key, exit 1, nothing written."""
    other = "spacing_y_mm" if key == "spacing_x_mm" else "spacing_x_mm"
    text = SMALL_CELL.replace("spacing_x_mm = 6.0", "spacing_x_mm = 6.0X").replace(
        "spacing_y_mm = 5.0", "spacing_y_mm = 6.0Y"
    )
    text = text.replace("6.0X" if key == "spacing_x_mm" else "6.0Y", "3.5")
    text = text.replace("6.0Y" if key == "spacing_x_mm" else "6.0X", "6.0")
    assert f"{key} = 3.5" in text and f"{other} = 6.0" in text
    out = tmp_path / "out"
    result = fruit("-q", "skin", _scene(tmp_path, text), "--out", out)
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and f"[grid].{key}" in lines[0] and "finger" in lines[0], lines
    assert "16 mm wide" in lines[0] and "14 mm" in lines[0] and "above 4 mm" in lines[0]
    assert not out.exists()


def test_fruit_run_refuses_the_narrow_cell_at_its_skin_stage(tmp_path, fruit):
    """Through the planner: the same one line, the stage before it complete, no skin
    folder."""
    scene = tmp_path / "pad.toml"
    scene.write_text(
        '[scene]\nname = "pad"\n[geometry]\npad_size_mm = [20.0, 20.0, 3.0]\n'
        "[grid]\ncount = [2, 2]\nspacing_x_mm = 3.5\nspacing_y_mm = 6.0\n"
        "[tracks]\ncover_mm = 1.5\n"
        '[skin]\nmodel = "electrostatic"\nyarn_radius_mm = 0.4\n'
        "[sensitivity]\nnoise_frames = 10\n"
    )
    out = tmp_path / "out"
    result = fruit("-q", "run", scene, "--out", out)
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "[grid].spacing_x_mm" in lines[0], lines
    assert (out / "pad-grid" / "taxels.csv").exists()
    assert not (out / "skin").exists()


def test_the_widest_object_fits_at_the_smallest_pitch_allowed():
    """At a pitch just above half the finger's radius, each pitch's key passes the check."""
    from fruitcli.electrostatics import design

    design._check_objects_fit("cell.toml", 4.01, 4.01)
    with pytest.raises(design.SceneError, match="spacing_x_mm"):
        design._check_objects_fit("cell.toml", 4.0, 4.01)


def test_track_radius_is_named_when_it_is_the_yarn(tmp_path, fruit):
    """Without [skin].yarn_radius_mm the yarn is [tracks].track_radius_mm: that key is named."""
    text = SMALL_CELL.replace("yarn_radius_mm = 0.4\n", "").replace(
        "track_radius_mm = 0.6", "track_radius_mm = 0.8"
    )
    result = fruit("-q", "skin", _scene(tmp_path, text), "--out", tmp_path / "out")
    assert result.exit_code == 1
    assert "[tracks].track_radius_mm" in result.output


def test_mesh_time_limit_is_named_and_nothing_is_written(tmp_path, fruit):
    """gmsh killed at [mesh].time_limit_s: one line naming it; an existing table stays as
    it was (complete, with its own inputs) and no temporary file is left."""
    out = tmp_path / "out"
    out.mkdir()
    (out / MARKER).write_text("{}\n")  # the folder of an earlier run
    (out / "summary.json").write_text("{}\n")
    text = SMALL_CELL + "\n[mesh]\ntime_limit_s = 0.05\n"
    result = fruit("-q", "skin", _scene(tmp_path, text), "--out", out)
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "[mesh].time_limit_s" in lines[0]
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "summary.json"]
    assert (out / "summary.json").read_text() == "{}\n"
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
