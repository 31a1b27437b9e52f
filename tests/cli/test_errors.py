"""Bad input across commands (from a sweep of every subcommand): one `Error:` line, a
non-zero exit code, nothing half-written; outputs readable by other users."""

import os

import numpy as np
from click.testing import CliRunner

from fruitcli.cli.main import cli
from tests.conftest import PAPER, ROOT


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def last_line(res):
    return res.output.strip().splitlines()[-1]


def test_unwritable_output_is_one_line(tmp_path):
    (tmp_path / "a_file").write_text("x")
    res = run(
        "evaluate",
        "--truth",
        PAPER / "paper_rest_truth.csv",
        "--measured",
        PAPER / "paper_rest_measured.csv",
        "--out",
        tmp_path / "a_file" / "sub",
    )
    assert res.exit_code == 1
    assert last_line(res).startswith(f"Error: --out {tmp_path / 'a_file' / 'sub'}: ")
    assert "Traceback" not in res.output


def test_outputs_have_the_usual_permissions(tmp_path):
    res = run(
        "evaluate",
        "--truth",
        PAPER / "paper_rest_truth.csv",
        "--measured",
        PAPER / "paper_rest_measured.csv",
        "--out",
        tmp_path / "o",
    )
    assert res.exit_code == 0, res.output
    umask = os.umask(0o022)
    os.umask(umask)
    for name in ("table.md", "summary.json", "errors.csv"):
        assert os.stat(tmp_path / "o" / name).st_mode & 0o777 == 0o666 & ~umask, name


def test_demo_checks_every_scene_name_before_running(tmp_path):
    res = run("demo", "--scenes", "paper-table,nosuch", "--out", tmp_path / "o")
    assert res.exit_code == 1 and "unknown scene 'nosuch' (bundled scenes: " in last_line(res)
    assert not (tmp_path / "o").exists()
    res = run("demo", "--scenes", ",,", "--out", tmp_path / "o")
    assert res.exit_code == 2 and "--scenes: expected at least one scene name" in res.output


def test_runtime_study_refuses_a_scene_without_fem(tmp_path):
    res = run("study", "runtime", ROOT / "pipelines" / "paper-table.toml", "--out", tmp_path / "o")
    assert res.exit_code == 2 and "the scene has no FEM to study" in res.output
    assert not (tmp_path / "o").exists()
    assert run("study", "stability", "--jobs", "0").exit_code == 2


def test_make_tracks_garbage_and_nan_origin(tmp_path):
    garbage = tmp_path / "g.stl"
    garbage.write_bytes(np.random.default_rng(0).bytes(3000))
    res = run("make-tracks", garbage, "--out", tmp_path / "o")
    assert res.exit_code == 1
    # random bytes read as a binary STL: its header's count does not match the file's size
    assert last_line(res) == (
        f"Error: {garbage}: binary STL header says 1,191,196,492 triangles (59,559,824,684 "
        "bytes), the file has 3,000 bytes (room for 58): truncated, or its header's count is "
        "wrong"
    )
    res = run("make-tracks", garbage, "--out", tmp_path / "o", "--origin-mm", "nan", "0")
    assert res.exit_code == 1
    assert last_line(res) == "Error: --origin-mm: expected two finite numbers (mm), got [nan, 0.0]"
    assert not (tmp_path / "o").exists()


def test_csv_saved_with_a_byte_order_mark_is_read(tmp_path):
    from fruitcli.tables import read_table

    path = tmp_path / "t.csv"
    path.write_bytes(b"\xef\xbb\xbfsample,x_mm,y_mm\n0,1,2\n")
    assert read_table(path, ["sample", "x_mm", "y_mm"])["x_mm"].tolist() == [1.0]


def test_mesh_far_too_large_for_its_unit_is_refused(tmp_path):
    """A mm mesh given as metres (150 km across) is refused at once, not reduced for
    minutes."""
    import trimesh

    art = tmp_path / "ball.stl"
    trimesh.creation.icosphere(2, 40.0).export(art)
    res = run("make-tracks", art, "--out", tmp_path / "o", "--unit", "m")
    assert res.exit_code == 1
    assert last_line(res) == (
        f"Error: {art}: the mesh is 8e+04 mm across in m, more than 5000 mm: is that its unit?"
    )


def test_a_mistyped_command_gets_the_closest_names():
    res = run("scene")
    assert res.exit_code == 2
    assert last_line(res) == "Error: No such command 'scene'. Did you mean 'scenes'?"
    assert (
        last_line(run("simualte")) == "Error: No such command 'simualte'. Did you mean 'simulate'?"
    )
    assert last_line(run("xyz")) == "Error: No such command 'xyz'."


def test_a_bundled_scene_name_points_to_scenes_copy(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for given in ("fruit-rest", "fruit-rest.toml"):
        res = run("run", given, "--out", "o")
        assert res.exit_code == 1
        assert last_line(res) == (
            f"Error: {given}: scene file not found; 'fruit-rest' is a bundled scene: copy it "
            "with `fruit scenes copy fruit-rest DIR`, then run DIR/fruit-rest.toml"
        )
    res = run("simulate", "nosuch", "--out", "o")
    assert res.exit_code == 1 and last_line(res) == "Error: nosuch: scene file not found"
    res = run("run", "elsewhere/fruit-rest.toml")  # a path: the user's own file, no hint
    assert last_line(res) == "Error: elsewhere/fruit-rest.toml: scene file not found"
    assert list(tmp_path.iterdir()) == []


def test_verbose_and_quiet_also_after_the_subcommand(tmp_path):
    """-v and -q after the subcommand count with those before it (the log level is set
    again; before it, logging.basicConfig set it in a fresh process)."""
    import logging

    from fruitcli.cli.main import log_level

    root = logging.getLogger()
    level = root.level
    try:
        for args, expected in (
            (["scenes", "-vv"], log_level(2, False)),
            (["-v", "scenes", "-v"], log_level(2, False)),
            (["scenes", "copy", "-q", "paper-table", tmp_path / "a"], logging.ERROR),
            (["study", "stability", "-v", "--jobs", "0"], None),  # a group's subcommand
        ):
            root.setLevel(logging.WARNING)
            res = run(*args)
            if expected is None:
                assert res.exit_code == 2 and "No such option" not in res.output
                assert root.level == log_level(1, False)
            else:
                assert res.exit_code == 0, res.output
                assert root.level == expected, args
    finally:
        root.setLevel(level)
    assert log_level(2, False) == logging.DEBUG
    assert "-v" not in run("scenes", "--help").output  # the group's options, not the command's


def test_help_lists_the_commands_without_importing_them():
    import subprocess
    import sys

    code = (
        "import sys; from fruitcli.cli.main import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "print(sorted(m for m in sys.modules if m.startswith('fruitcli.cli.')))"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert "  simulate         Quasi-static FEM of a scene's states" in res.stdout
    assert res.stdout.strip().splitlines()[-1] == "['fruitcli.cli.main']"


def test_a_library_warning_is_one_line(capsys):
    import warnings

    from fruitcli.cli.main import show_warning

    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = show_warning
        warnings.warn("overflow encountered\nin multiply", RuntimeWarning, stacklevel=1)
    err = capsys.readouterr().err
    assert err == "warning: RuntimeWarning: overflow encountered in multiply\n"
