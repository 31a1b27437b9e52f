"""Scene keys out of range and options that are not finite: one line naming the key, before
anything runs; a scene with [sensitivity] but no FEM runs with the taxels at rest."""

import json

import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import SceneError
from fruitcli.scene import load_scene

TAXELS = "id,i,j,x_mm,y_mm,z_mm\n0,0,0,0,0,0\n1,1,0,16,0,0\n2,0,1,0,12,0\n3,1,1,16,12,0\n"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def scene_file(tmp_path, body):
    (tmp_path / "taxels.csv").write_text(TAXELS)
    path = tmp_path / "s.toml"
    path.write_text('[scene]\nname = "s"\n[grid]\ntaxels = "taxels.csv"\n' + body)
    return path


@pytest.mark.parametrize(
    "body, message",
    [
        ("[bench]\nseed = -1\n", "[bench].seed: expected a seed >= 0, got -1"),
        (
            "[sensitivity]\nanimation_frames = 0\n",
            "[sensitivity].animation_frames: expected frames >= 1, got 0",
        ),
        (
            "[sensitivity]\nnoise_frames = -1\n",
            "[sensitivity].noise_frames: expected frames >= 2 (a standard deviation needs two), "
            "got -1",
        ),
        (
            "[sensitivity]\nnoise_frames = 0\n",
            "[sensitivity].noise_frames: expected frames >= 2 (a standard deviation needs two), "
            "got 0",
        ),
        (
            "[detection]\ndrift_rate = 5.0\n",
            "[detection].drift_rate: expected a rate per frame 0 <= rate <= 1, got 5.0",
        ),
        ("[tracks]\nfaces = 10000000000000000000000\n", None),  # TOML: beyond a 64-bit integer
        (
            "[tracks]\nfaces = 1000000000000000000\n",
            "[tracks].faces: expected a triangle count 4 <= faces <= 10,000,000, got "
            "1000000000000000000",
        ),
    ],
)
def test_keys_out_of_range_are_one_line(tmp_path, body, message):
    path = scene_file(tmp_path, body)
    with pytest.raises(SceneError) as err:
        load_scene(path)
    if message is not None:
        assert str(err.value) == f"s.toml: {message}"
    res = run("run", path, "--out", tmp_path / "o")
    assert res.exit_code == 1 and res.output.strip().splitlines()[-1].startswith("Error: ")
    assert "Traceback" not in res.output and not (tmp_path / "o").exists()


def test_an_empty_scene_is_refused(tmp_path):
    path = tmp_path / "empty.toml"
    path.write_text("# nothing\n")
    res = run("run", path, "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert res.output.strip().splitlines()[-1] == (
        "Error: empty.toml: the scene declares no section; expected at least [scene] and what "
        "to run ([geometry], [[evaluate]], ...)"
    )
    assert not (tmp_path / "o").exists()


def test_sensitivity_without_fem_has_no_shift(tmp_path):
    path = scene_file(tmp_path, "[sensitivity]\nnoise_frames = 400\nanimation_frames = 3\n")
    res = run("run", path, "--out", tmp_path / "o")
    assert res.exit_code == 0, res.output
    out = json.loads((tmp_path / "o" / "sensitivity" / "sensitivity.json").read_text())
    assert out["states"] == 1 and out["noise_frames"] == 400
    assert all(t["max_shift_model"] == 0.0 and t["strain_max"] == 0.0 for t in out["taxels"])
    # the noise std of 400 frames is within 15 % of the skin's noise (0.5 to 1.85 counts)
    assert all(0.5 * 0.85 < t["std"] < 1.85 * 1.15 for t in out["taxels"])


@pytest.mark.parametrize(
    "args, option",
    [
        (["make-tracks", "x.stl", "--spacing-x-mm", "inf"], "--spacing-x-mm"),
        (["locate", "x.log", "--taxels", "t.csv", "--threshold", "nan"], "--threshold"),
        (
            ["evaluate", "--truth", "t.csv", "--measured", "m.csv", "--reference-length-mm", "inf"],
            "--reference-length-mm",
        ),
    ],
)
def test_options_that_are_not_finite_are_refused(tmp_path, args, option):
    res = run(*args, "--out", tmp_path / "o")
    assert res.exit_code == 2, res.output
    assert (
        f"Invalid value for '{option}'" in res.output and "expected a finite number" in res.output
    )


def test_make_tracks_faces_beyond_the_limit_are_refused(tmp_path):
    res = run("make-tracks", "x.stl", "--faces", "10000000000000000000000", "--out", tmp_path / "o")
    assert (
        res.exit_code == 2
        and "'--faces': 10000000000000000000000 is not in the range 4<=x<=10000000" in res.output
    )


def test_a_duplicate_evaluate_label_is_one_line(tmp_path):
    from tests.conftest import PAPER

    row = (
        f'[[evaluate]]\nlabel = "Rest"\ntruth = "{PAPER / "paper_rest_truth.csv"}"\n'
        f'measured = "{PAPER / "paper_rest_measured.csv"}"\n'
    )
    path = tmp_path / "e.toml"
    path.write_text('[scene]\nname = "e"\n' + row + row)
    res = run("run", path, "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert res.output.strip().splitlines()[-1] == (
        "Error: e.toml: [[evaluate]].label: 'Rest' is given twice; expected one label per row "
        "(it names the row's folder and table line)"
    )


def test_a_bench_too_large_for_memory_is_one_line(tmp_path, monkeypatch):
    from fruitcli import memory

    monkeypatch.setattr(memory, "available_bytes", lambda: 1024**3)  # 1 GiB
    path = scene_file(tmp_path, "[bench]\nbaseline_frames = 10000000\n")
    res = run("run", path, "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert res.output.strip().splitlines()[-1] == (
        "Error: s.toml: [bench].baseline_frames = 10000000 needs about 24.4 GiB of memory, "
        "1.0 GiB is available"
    )


def test_record_into_a_missing_folder_creates_nothing(tmp_path):
    out = tmp_path / "nodir" / "x.npz"
    res = run("record", "--port", "loop://", "--out", out, "--seconds", "0.2")
    assert res.exit_code == 1
    assert res.output.strip().splitlines()[-1] == (
        f"Error: --out {out}: folder {out.parent} does not exist; create it first"
    )
    assert list(tmp_path.iterdir()) == []


def test_a_bench_whose_samples_all_miss_the_body_is_one_line(tmp_path):
    (tmp_path / "far.csv").write_text("sample,x_mm,y_mm\n0,500,500\n1,600,600\n")
    path = scene_file(tmp_path, '[bench]\nsamples = "far.csv"\n')
    res = run("run", path, "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert res.output.strip().splitlines()[-1] == (
        "Error: s.toml: [bench].samples: none of the 2 sample points lies over the taxels' "
        "interpolated surface (no body surface given); expected points (x, y) over the body"
    )
    assert not (tmp_path / "o" / "bench" / "manifest.json").exists()


def test_a_moved_clamp_is_a_deformation(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text(
        '[scene]\nname = "c"\n[geometry]\npad_size_mm = [40.0, 40.0, 3.0]\n'
        "[grid]\ncount = [2, 2]\n[[fixed]]\nbox_mm = [-21, -21, -1, -15, 21, 4]\n"
        "displacement_mm = [0.0, 0.0, 2.0]\n[sensitivity]\nnoise_frames = 50\n"
    )
    res = run("run", path, "--out", tmp_path / "o", "--dry-run")
    assert res.exit_code == 0, res.output
    plan = {
        line.split()[0]: line.split()[1]
        for line in res.output.splitlines()
        if line.split() and line.split()[0] in ("tetra", "simulate", "sensitivity")
    }
    assert plan == {"tetra": "run", "simulate": "run", "sensitivity": "run"}
