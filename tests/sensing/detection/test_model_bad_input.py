"""Bad input for ``method = "model"`` on the command line: one line naming the file and
key, exit 1, an earlier output left as it was."""

from __future__ import annotations

from click.testing import CliRunner

from fruitcli.cli.main import cli
from tests.sensing.skin.test_calibrate import bench_and_calibrate, virtual_bench_scene


def test_a_skin_file_without_the_footprint_is_one_line_for_the_model(tmp_path):
    virtual_bench_scene(tmp_path)
    cal = bench_and_calibrate(tmp_path, "b")
    given = (cal / "skin.toml").read_text()
    assert "footprint_sigma_mm" in given
    bare = cal / "no-footprint.toml"
    bare.write_text("".join(ln for ln in given.splitlines(True) if "footprint" not in ln))
    frames, out = tmp_path / "b" / "small" / "frames.npz", tmp_path / "located"

    def locate(skin, method):
        args = ["locate", str(frames), "--taxels", str(tmp_path / "t.csv"), "--skin", str(skin)]
        return CliRunner().invoke(cli, [*args, "--method", method, "--out", str(out)])

    res = locate(cal / "skin.toml", "model")
    assert res.exit_code == 0, res.output
    before = (out / "touches.csv").read_bytes()
    assert b",fit\n" in before
    res = locate(bare, "model")
    assert res.exit_code == 1
    assert res.output.strip().splitlines() == [
        f'Error: {bare}: [skin].footprint_sigma_mm: missing; [detection].method = "model" '
        "fits the skin's footprint at its calibrated width (fruit calibrate writes it)"
    ]
    assert (out / "touches.csv").read_bytes() == before  # the earlier run's file kept
    # the other methods do not fit the footprint: the same file serves them
    res = locate(bare, "n9")
    assert res.exit_code == 0, res.output


def test_live_with_the_model_and_a_skin_file_without_the_footprint_is_one_line(tmp_path):
    """Checked before any port is opened: the port here does not exist."""
    virtual_bench_scene(tmp_path)
    scene = tmp_path / "s.toml"
    scene.write_text(scene.read_text() + '[detection]\nmethod = "model"\n')
    bare = tmp_path / "no-footprint.toml"
    bare.write_text("[skin]\ncontact_counts = 70.0\ngap_decay_mm = 2.0\n")
    args = ["live", str(scene), "--port", str(tmp_path / "no-port"), "--taxels"]
    res = CliRunner().invoke(cli, [*args, str(tmp_path / "t.csv"), "--skin", str(bare)])
    assert res.exit_code == 1
    assert res.output.strip().splitlines() == [
        f'Error: {bare}: [skin].footprint_sigma_mm: missing; [detection].method = "model" '
        "fits the skin's footprint at its calibrated width (fruit calibrate writes it)"
    ]
