"""The electrostatic skin ([skin].model = "electrostatic") on the 4 x 4 pad: `fruit run`
builds the crossing's table in a stage `skin` and reuses it; the bench's activations are
the table's counts; the bent pad's shift is the table's bend; the Gaussian default's
outputs do not depend on the electrostatic keys."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fruitcli.scene import parse_scene
from fruitcli.sensing.detection.locate import load_states
from fruitcli.sensing.frames.board import taxel_cells
from fruitcli.sensing.frames.recording import read_npz
from fruitcli.sensing.skin import forward
from fruitcli.sensing.skin.crossing_skin import (
    CrossingSkin,
    _odd_interp,
    yarn_deformation,
)
from fruitcli.sensing.stages import run_bench, run_sensitivity
from fruitcli.tables import read_taxels
from tests.sensing.skin.test_virtual_bench import pad_states, pad_taxel_csv

PAD = """
[grid]
spacing_x_mm = 16.0
spacing_y_mm = 16.0
taxels = "taxels.csv"

[bench]
indenters = ["small", "medium"]
samples = "samples.csv"
step_mm = 0.25
seed = 3

[skin]
model = "electrostatic"
gaps_mm = [0.0, 1.0, 2.0]
noise_std_counts = 0.0
"""


def _pad_scene(tmp_path: Path, text: str = PAD) -> Path:
    pad_taxel_csv(tmp_path / "taxels.csv")
    xy = forward.pad_taxels_mm()[[5, 10], :2]  # right over two inner taxels
    rows = ["sample,x_mm,y_mm"] + [f"{k},{x},{y}" for k, (x, y) in enumerate(xy)]
    (tmp_path / "samples.csv").write_text("\n".join(rows) + "\n")
    path = tmp_path / "pad.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def pad_run(tmp_path_factory):
    """`fruit run` of the electrostatic pad bench, then once more (reuse)."""
    from click.testing import CliRunner

    from fruitcli.cli.main import cli

    tmp = tmp_path_factory.mktemp("pad")
    scene = _pad_scene(tmp)
    out = tmp / "out"
    runner = CliRunner()
    first = runner.invoke(cli, ["run", str(scene), "--out", str(out)], catch_exceptions=False)
    second = runner.invoke(
        cli, ["run", str(scene), "--out", str(out), "--dry-run"], catch_exceptions=False
    )
    return tmp, out, first, second


@pytest.mark.slow
def test_fruit_run_builds_the_table_then_reuses_it(pad_run):
    tmp, out, first, second = pad_run
    assert first.exit_code == 0, first.output
    assert (out / "skin" / "crossing.npz").exists() and (out / "skin" / "summary.json").exists()
    for ind in ("small", "medium"):
        assert (out / "bench" / ind / "frames.npz").exists()
        assert (out / "evaluate" / "summary.json").exists()
    assert second.exit_code == 0, second.output
    plan = {line.split()[0]: line.split()[1] for line in second.output.splitlines()[1:]}
    assert plan["skin"] == "reuse" and plan["bench"] == "reuse", second.output


@pytest.mark.slow
def test_bench_activation_is_the_tables_counts(pad_run):
    tmp, out, first, _ = pad_run
    assert first.exit_code == 0, first.output
    table = CrossingSkin.load(out / "skin")
    summary = json.loads((out / "skin" / "summary.json").read_text())
    scene = parse_scene((tmp / "pad.toml").read_text(), tmp / "pad.toml")
    taxels = read_taxels(tmp / "taxels.csv")
    rows, cols = taxel_cells(taxels, scene.board, "taxels.csv")
    skin = forward.make_skin(16, 3, forward.SkinParams.from_table(scene.skin), taxels.ids)
    for name in ("small", "medium"):
        k = table.objects.index(name)
        rec = read_npz(out / "bench" / name / "frames.npz")
        idle = scene.bench.baseline_frames
        frames = rec.frames[:, rows, cols]
        first_sample = np.flatnonzero(rec.sample == 0)[0]
        # sample 0 is over taxel 5: its frames from the start gap down, step 0.25 mm
        approach = frames[idle : first_sample + 1, 5] - skin.baseline_counts[5]
        gaps = 5.0 - 0.25 * np.arange(len(approach))
        expected = table.drop(name, 0.0, 0.0, gaps)
        assert np.all(np.abs(approach - expected) <= 0.5 + 1e-9)
        # at the table's gaps the table's own counts; between them, linear
        dc = -summary["counts_per_ff"] * np.load(out / "skin" / "crossing.npz")["dc_ff"]
        centre = dc[k, :, len(table.dx_mm) // 2, len(table.dy_mm) // 2]
        assert table.dx_mm[len(table.dx_mm) // 2] == 0 == table.dy_mm[len(table.dy_mm) // 2]
        assert table.drop(name, 0.0, 0.0, 0.0) == pytest.approx(
            summary["objects"][name]["contact_counts"], rel=1e-9
        )
        assert table.drop(name, 0.0, 0.0, [0.0, 1.0, 2.0]) == pytest.approx(centre, rel=1e-9)
        assert table.drop(name, 0.0, 0.0, 0.5) == pytest.approx(centre[:2].mean(), rel=1e-9)
        assert np.all(np.diff(table.drop(name, 0.0, 0.0, np.linspace(0, 5, 21))) < 0)
        crossed = gaps[-1]
        if summary["objects"][name]["contact_counts"] > scene.detection.threshold_counts:
            assert table.drop(name, 0.0, 0.0, crossed) > scene.detection.threshold_counts - 1
            assert (
                table.drop(name, 0.0, 0.0, crossed + 0.25) <= scene.detection.threshold_counts + 1
            )


def _synthetic_table() -> CrossingSkin:
    gap = np.array([0.0, 1.0, 2.0])
    d = np.array([-4.0, -2.0, 0.0, 2.0, 4.0])
    gx, gy = np.meshgrid(d, d, indexing="ij")
    lateral = np.exp(-(gx**2 + gy**2) / 18.0)
    drop = 40.0 * np.exp(-gap / 2.0)[:, None, None] * lateral[None]
    return CrossingSkin(
        ("small",),
        gap,
        d,
        d,
        drop[None],
        np.array([3.0]),
        np.array([2.0]),
        np.array([2.0]),
        np.array([0.0, 0.1, 0.2]),
        np.array([0.0, 0.05]),
        np.array([[0.0, 1.0, 3.0], [0.0, -1.0, -2.0]]),
        np.array([[0.0, 4.0], [0.0, 10.0]]),
        1.5,
        0.5,
    )


def test_offsets_and_gaps_beyond_the_table_continue_it():
    t = _synthetic_table()
    edge = t.drop("small", 4.0, 0.0, 0.0)
    assert t.drop("small", 6.0, 0.0, 0.0) == pytest.approx(edge * np.exp(-0.5 * 20 / 9.0))
    assert t.drop("small", 0.0, 0.0, 3.0) == pytest.approx(40.0 * np.exp(-1.5))
    assert t.drop("small", 0.0, 0.0, -1.0) == pytest.approx(40.0 * np.exp(0.5))  # pressed
    # between offsets Catmull-Rom: at the middle -1/16, 9/16, 9/16, -1/16 of four nodes
    near, far = np.exp(-4 / 18), np.exp(-16 / 18)
    middle = 40.0 * (-near + 9.0 + 9.0 * near - far) / 16.0
    assert t.drop("small", 1.0, 0.0, 0.0) == pytest.approx(middle, rel=1e-12)
    assert t.drop("small", 2.0, 2.0, 0.0) == pytest.approx(40.0 * np.exp(-8 / 18), rel=1e-12)
    with pytest.raises(Exception, match="indenter"):
        t.drop("finger", 0.0, 0.0, 0.0)


def test_shift_is_the_bend_plus_the_stretch_left_over():
    t = _synthetic_table()
    k_s = 0.05 / (1 + 1.5 * 0.05)  # the surface's curvature when the neutral plane's is 0.05
    shift = t.deformation_shift(np.array([[1.5 * 0.05, 0.0]]), np.array([[k_s, 0.0]]))
    assert shift[0] == pytest.approx(4.0)
    shift = t.deformation_shift(np.array([[0.0, 0.15]]), np.array([[0.0, 0.0]]))
    assert shift[0] == pytest.approx(-1.5)
    assert _odd_interp(np.array([-0.15, 0.3]), t.strain, t.stretch_counts[0]) == pytest.approx(
        [-2.0, 5.0]
    )


def test_bent_pad_surface_stretch_and_curvature(tmp_path):
    # the pad's mid-plane wraps a cylinder of radius R: its top, 1.5 mm out, is curved
    # 1 / (R + 1.5) and stretched 1.5 / R along x, not at all along y
    states = load_states(pad_states(tmp_path / "s.npz", (0.0, 180.0)))
    stretch, curv = yarn_deformation(states)
    radius = 48.0 / np.pi
    assert np.abs(stretch[0]).max() < 1e-12 and np.abs(curv[0]).max() < 1e-12
    assert curv[1, :, 0] == pytest.approx(np.full(16, 1 / (radius + 1.5)), rel=0.01)
    assert stretch[1, :, 0] == pytest.approx(np.full(16, 1.5 / radius), rel=0.05)
    assert np.abs(curv[1, :, 1]).max() < 1e-6 and np.abs(stretch[1, :, 1]).max() < 1e-6


def test_a_body_curved_at_rest_has_no_shift_at_rest(tmp_path):
    # the pad bent at rest: its C0 is that of the bent crossing; bending it back flat
    # shifts by minus the bend's counts
    from types import SimpleNamespace

    from fruitcli.fem.elements.barycentric import locate
    from fruitcli.fem.meshing.topology import boundary_faces
    from fruitcli.sensing.skin.crossing_skin import shift_counts

    flat, tets = forward.pad_mesh()
    radius = 48.0 / np.pi
    bent = forward.bend_nodes(flat, radius, 3.0)
    k, bary, _ = locate(flat, tets, forward.pad_taxels_mm(z_mm=3.0 - 1e-6))
    states = SimpleNamespace(
        rest_nodes=bent,
        tets=tets,
        surface_tris=boundary_faces(flat, tets),
        displacement_mm=np.array([bent - bent, flat - bent]),
        taxel_tet=k,
        taxel_bary=bary,
    )
    table = _synthetic_table()
    shift = shift_counts(states, table, np.ones(16))
    assert np.abs(shift[0]).max() < 1e-9
    # back to flat: the bend's shift at the pad's curvature (0.065 per mm, beyond the
    # table's 0.05: its last two points' slope), less the stretch left over
    kappa = 1 / radius
    assert shift[1] == pytest.approx(np.full(16, -4.0 * kappa / 0.05), abs=0.3)


def test_bent_pad_shift_is_the_tables_bend(tmp_path):
    table = _synthetic_table()
    tables = tmp_path / "skin"
    tables.mkdir()
    np.savez(
        tables / "crossing.npz",
        c0_ff=np.array(100.0),
        objects=np.array(["small"]),
        gap_mm=table.gap_mm,
        dx_mm=table.dx_mm,
        dy_mm=table.dy_mm,
        dc_ff=-table.drop_counts / 0.5,
        strain=table.strain,
        curvature_per_mm=np.array([0.0, np.pi / 48]),
        c_stretch_ff=100.0 - table.stretch_counts / 0.5,
        c_bend_ff=100.0 - table.bend_counts / 0.5,
    )
    (tmp_path / "skin" / "summary.json").write_text(
        json.dumps(
            {
                "counts_per_ff": 0.5,
                "objects": {"small": {"footprint_sigma_mm": 3.0, "gap_decay_mm": 2.0}},
            }
        )
    )
    states = pad_states(tmp_path / "s.npz")
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    text = (
        "[grid]\nspacing_x_mm = 16.0\nspacing_y_mm = 16.0\n[sensitivity]\n"
        '[skin]\nmodel = "electrostatic"\n'
    )
    sc = parse_scene(text, tmp_path / "pad.toml", must_exist=False)
    out = run_sensitivity(sc, taxels, states, tmp_path / "sens", crossing_dir=tables)
    fab = np.array([t["fab"] for t in out["taxels"]])
    model = np.array([t["max_shift_model"] for t in out["taxels"]])
    # bent about y: curved along x to the pad's curvature, the table's bend_x (4 counts)
    assert model[fab == 1] == pytest.approx(np.full((fab == 1).sum(), 4.0), abs=0.3)
    assert out["skin_model"] == "electrostatic" and out["counts_per_ff"] == 0.5


def test_gaussian_outputs_do_not_depend_on_the_electrostatic_keys(tmp_path):
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    states = pad_states(tmp_path / "s.npz")
    base = "[grid]\nspacing_x_mm = 16.0\nspacing_y_mm = 16.0\n[bench]\nstate = 2\n"
    plain = parse_scene(base, tmp_path / "a.toml", must_exist=False)
    keyed = parse_scene(
        base + '[skin]\nmodel = "gaussian"\npermittivity = 3.5\ngaps_mm = [0.0, 1.0]\n',
        tmp_path / "b.toml",
        must_exist=False,
    )
    run_bench(plain, taxels, states, tmp_path / "a")
    run_bench(keyed, taxels, states, tmp_path / "b", crossing_dir=tmp_path / "none")
    for ind in ("small", "medium"):
        a = read_npz(tmp_path / "a" / ind / "frames.npz")
        b = read_npz(tmp_path / "b" / ind / "frames.npz")
        assert np.array_equal(a.frames, b.frames) and np.array_equal(a.sample, b.sample)
        assert (tmp_path / "a" / ind / "truth.csv").read_bytes() == (
            tmp_path / "b" / ind / "truth.csv"
        ).read_bytes()


def test_a_yarn_that_does_not_fit_stops_the_run_naming_the_key(tmp_path, fruit):
    scene = _pad_scene(tmp_path, PAD + "yarn_radius_mm = 2.5\n")
    out = tmp_path / "out"
    result = fruit("run", scene, "--out", out)
    assert result.exit_code != 0
    lines = result.output.strip().splitlines()
    assert "[skin].yarn_radius_mm" in lines[-1] and "Traceback" not in result.output
    assert not (out / "skin" / "crossing.npz").exists() and not (out / "bench").exists()


def test_gaussian_scene_plans_no_skin_stage(tmp_path, fruit):
    scene = _pad_scene(tmp_path, PAD.replace('model = "electrostatic"', 'model = "gaussian"'))
    result = fruit("run", scene, "--out", tmp_path / "out", "--dry-run")
    assert result.exit_code == 0, result.output
    skin = [line for line in result.output.splitlines() if line.startswith("skin ")]
    assert skin and "not needed" in skin[0]


@pytest.mark.slow
def test_fruit_calibrate_on_the_electrostatic_bench_gives_back_its_counts_per_ff(
    pad_run, monkeypatch
):
    """`fruit calibrate` of the electrostatic pad bench (noise 0, gains 1) with the same
    scene: the skin stage's table is reused (out/<scene>/skin, copied from the run) and
    its counts per fF come back; skin.toml says model = "electrostatic"."""
    import shutil

    from click.testing import CliRunner

    from fruitcli.cli.main import cli
    from fruitcli.scene import load_skin_table

    tmp, out, first, _ = pad_run
    assert first.exit_code == 0, first.output
    monkeypatch.chdir(tmp)
    shutil.copytree(out / "skin", tmp / "out" / "pad" / "skin", dirs_exist_ok=True)
    summary = json.loads((out / "skin" / "summary.json").read_text())
    res = CliRunner().invoke(
        cli,
        [
            "calibrate",
            str(out / "bench" / "small" / "frames.npz"),
            "--truth",
            str(out / "bench" / "small" / "truth.csv"),
            "--scene",
            str(tmp / "pad.toml"),
            "--out",
            str(tmp / "cal"),
        ],
    )
    assert res.exit_code == 0, res.output
    assert "electrostatic skin" in res.output and "skin: reuse" in res.output
    cal = json.loads((tmp / "cal" / "calibration.json").read_text())
    # activations rounded to whole counts near the threshold: within 2 %
    assert cal["counts_per_ff"] == pytest.approx(summary["counts_per_ff"], rel=0.02)
    skin = load_skin_table(tmp / "cal" / "skin.toml")
    assert skin.model == "electrostatic" and skin.gaps_mm == [0.0, 1.0, 2.0]
