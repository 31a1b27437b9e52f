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
        ("[bench]\nseed = -1\n", "[bench].seed: expected a seed 0 <= seed < 2^63, got -1"),
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


PAD = '[scene]\nname = "g"\n[geometry]\npad_size_mm = [20.0, 20.0, 3.0]\n'
HOLD = "[[fixed]]\nbox_mm = [-11, -11, -1, 11, 11, 0.1]\n"


def test_an_empty_gravity_section_is_its_default(tmp_path):
    """An empty [gravity] means vector_m_s2 = [0, 0, -9.81]: a held body is simulated."""
    path = tmp_path / "g.toml"
    path.write_text(PAD + "[gravity]\n" + HOLD)
    scene = load_scene(path)
    assert scene.has("gravity") and scene.gravity.vector_m_s2 == [0.0, 0.0, -9.81]
    res = run("run", path, "--dry-run", "--out", tmp_path / "o")
    assert res.exit_code == 0, res.output
    lines = {line.split()[0]: line for line in res.output.splitlines()[1:]}
    assert "run" in lines["simulate"] and "gravity on the held body" in lines["simulate"]


def test_gravity_without_a_hold_is_said(tmp_path):
    """Gravity on a body nothing holds is left out, and the plan and one warning say so."""
    path = tmp_path / "g.toml"
    path.write_text(PAD + "[gravity]\n")
    res = CliRunner().invoke(cli, ["run", str(path), "--dry-run", "--out", str(tmp_path / "o")])
    assert res.exit_code == 0, res.output
    why = (
        "[gravity] left out: no [[fixed]] region or [[jig]] holds the body (a free body would "
        "only fall)"
    )
    assert res.output.count(f"warning: {why}") == 1
    (line,) = [ln for ln in res.output.splitlines() if ln.startswith("simulate ")]
    assert line.split()[1:3] == ["not", "needed"] and line.endswith(why)


@pytest.fixture
def one_gib(monkeypatch):
    from fruitcli import memory

    monkeypatch.setattr(memory, "available_bytes", lambda: 1024**3)


def last_line(res) -> str:
    return res.output.strip().splitlines()[-1]


def test_a_tiny_bench_step_is_refused_before_it_allocates(tmp_path, one_gib):
    path = scene_file(tmp_path, "[bench]\nstep_mm = 1e-9\n")
    res = run("run", path, "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert last_line(res).startswith("Error: s.toml: [bench].step_mm = 1e-09 over ")
    assert last_line(res).endswith(" TiB of memory, 1.0 GiB is available")


def test_a_pad_grid_too_large_for_memory_is_one_line(tmp_path, one_gib):
    path = tmp_path / "p.toml"
    path.write_text(
        '[scene]\nname = "p"\n[geometry]\npad_size_mm = [100.0, 100.0, 3.0]\n'
        "[grid]\ncount = [10000, 10000]\nspacing_x_mm = 0.001\nspacing_y_mm = 0.001\n"
    )
    res = run("run", path, "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert last_line(res) == (
        "Error: p.toml: [grid].count = [10000, 10000] on pad_size_mm = [100.0, 100.0, 3.0] "
        "(100,000,000 taxels, 4,020,000 track points) needs about 38.8 GiB of memory, "
        "1.0 GiB is available"
    )


@pytest.mark.parametrize(
    "size, line",
    [
        (
            "1e-3",
            "Error: t.toml: [mesh].size_mm = 0.001 on pad (1200 mm^3): about 5.4e+12 tets "
            "needs about 9822.5 TiB of memory, 1.0 GiB is available",
        ),
        (
            "0.05",
            "Error: t.toml: [mesh].size_mm = 0.05 on pad (1200 mm^3): about 4.32e+07 tets "
            "needs about 80.5 GiB of memory, 1.0 GiB is available",
        ),
    ],
)
def test_a_mesh_too_fine_is_refused_before_gmsh(tmp_path, one_gib, size, line):
    path = tmp_path / "t.toml"
    path.write_text(
        f'[scene]\nname = "t"\n[geometry]\npad_size_mm = [20.0, 20.0, 3.0]\n[mesh]\n'
        f"size_mm = {size}\n"
    )
    res = run("tetra", path, "--out", tmp_path / "o")
    assert res.exit_code == 1 and last_line(res).startswith(line), res.output
    assert not (tmp_path / "o").exists()


def test_a_mesh_gmsh_cannot_make_in_time_is_refused(tmp_path):
    path = tmp_path / "t.toml"
    path.write_text(
        '[scene]\nname = "t"\n[geometry]\npad_size_mm = [20.0, 20.0, 3.0]\n[mesh]\n'
        "size_mm = 0.2\ntime_limit_s = 1\n"
    )
    res = run("tetra", path, "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert last_line(res) == (
        "Error: t.toml: [mesh].size_mm = 0.2 on pad (1200 mm^3): about 6.75e+05 tets take "
        "gmsh at least 13.5 s, more than [mesh].time_limit_s = 1 s; use a larger size_mm"
    )


def test_a_reduction_too_fine_for_memory_is_one_line(tmp_path, one_gib):
    import trimesh

    trimesh.creation.icosphere(3, 20.0).export(tmp_path / "sphere.stl")
    res = run(
        "make-tracks", tmp_path / "sphere.stl", "--faces", 10_000_000, "--out", tmp_path / "o"
    )
    assert res.exit_code == 1
    assert last_line(res).startswith(
        "Error: --faces = 10,000,000 on sphere.stl (a distance grid of 2.85e+10 points) needs "
        "about 1.7 TiB of memory, 1.0 GiB is available"
    )
    assert not (tmp_path / "o").exists()


def test_a_solid_far_too_large_is_refused_by_tetra(tmp_path):
    import trimesh

    trimesh.creation.box([1e8, 1e8, 1e8]).export(tmp_path / "big.stl")
    path = tmp_path / "t.toml"
    path.write_text('[scene]\nname = "t"\n')
    res = run("tetra", path, "--solid", tmp_path / "big.stl", "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert last_line(res) == (
        "Error: --solid: big.stl is 1e+08 mm across, more than 5000 mm: is that its unit?"
    )


def test_sensitivity_frames_too_many_for_memory_are_one_line(tmp_path, one_gib):
    path = scene_file(tmp_path, "[sensitivity]\nnoise_frames = 100000000\n")
    res = run("run", path, "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert last_line(res) == (
        "Error: s.toml: [sensitivity].noise_frames = 100000000 over 4 taxels needs about "
        "11.9 GiB of memory, 1.0 GiB is available"
    )
