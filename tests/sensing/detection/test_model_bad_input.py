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


def _states(path, taxels_mm, lift_mm, drop=()):
    """states.npz of two states, the taxels at rest and lifted by `lift_mm` in z (a
    one-tet mesh: what the model method reads of a state is its taxels), keys in `drop`
    left out."""
    import numpy as np

    tax = np.stack([taxels_mm, taxels_mm + [0.0, 0.0, lift_mm]])
    arrays = {
        "rest_nodes": np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]),
        "tets": np.array([[0, 1, 2, 3]]),
        "surface_tris": np.array([[0, 1, 2]]),
        "displacement_mm": np.zeros((2, 4, 3)),
        "pressure_kpa": np.zeros((2, 1)),
        "chamber_names": np.array(["c"]),
        "taxels_mm": tax,
        "taxel_tet": np.zeros(len(taxels_mm), np.int64),
        "taxel_bary": np.full((len(taxels_mm), 4), 0.25),
    }
    np.savez(path, **{k: v for k, v in arrays.items() if k not in drop})


def _with_state(src, dst, state):
    """A copy of bench recording `src` whose meta names FEM state `state`."""
    import json

    import numpy as np

    with np.load(src) as f:
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(str(arrays["meta"]))
    arrays["meta"] = np.array(json.dumps({**meta, "state": state}))
    np.savez(dst, **arrays)


def test_the_model_on_a_deformed_state_needs_its_taxels_not_a_surface(tmp_path):
    """The tangent frames come from the state's taxels: without --surface the model
    locates on them; a state the file lacks, or a file without the taxels, is one line."""
    import csv

    from fruitcli.tables import read_taxels

    virtual_bench_scene(tmp_path)
    cal = bench_and_calibrate(tmp_path, "b")
    taxels = tmp_path / "t.csv"
    _states(tmp_path / "states.npz", read_taxels(taxels).xyz_mm, 5.0)
    _with_state(tmp_path / "b" / "small" / "frames.npz", tmp_path / "lifted.npz", 1)

    def locate(frames, states, out):
        args = ["locate", str(frames), "--taxels", str(taxels), "--states", str(states)]
        args += ["--skin", str(cal / "skin.toml"), "--method", "model", "--out", str(out)]
        return CliRunner().invoke(cli, args)

    res = locate(tmp_path / "lifted.npz", tmp_path / "states.npz", tmp_path / "lifted")
    assert res.exit_code == 0, res.output
    with open(tmp_path / "lifted" / "touches.csv") as fh:
        rows = list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))
    fitted = [r for r in rows if r["fit"] == "model"]
    # most are placed by the model; a touch right over a taxel (a 4.5 mm footprint on a
    # 16 mm pitch: its neighbours read a fraction of a count) may keep N9's point on the
    # fit's uncertainty
    assert len(fitted) > 0.7 * len(rows)
    # the pad is flat (its taxels at one height): on the lifted state's taxels every
    # fitted point is 5 mm above them
    (rest_z,) = set(read_taxels(taxels).xyz_mm[:, 2])
    assert {round(float(r["z_mm"]) - 5.0, 6) for r in fitted} == {round(rest_z, 6)}

    _with_state(tmp_path / "b" / "small" / "frames.npz", tmp_path / "far.npz", 7)
    res = locate(tmp_path / "far.npz", tmp_path / "states.npz", tmp_path / "far")
    assert res.exit_code == 1
    assert res.output.strip().splitlines() == [
        f"Error: {tmp_path / 'far.npz'}: meta state 7 not in the states (0..1)"
    ]
    assert not (tmp_path / "far").exists()

    _states(tmp_path / "bare.npz", read_taxels(taxels).xyz_mm, 5.0, drop=("taxels_mm",))
    res = locate(tmp_path / "lifted.npz", tmp_path / "bare.npz", tmp_path / "bare")
    assert res.exit_code == 1
    assert res.output.strip().splitlines() == [
        f"Error: {tmp_path / 'bare.npz'}: missing key(s) taxels_mm"
    ]
    assert not (tmp_path / "bare").exists()
