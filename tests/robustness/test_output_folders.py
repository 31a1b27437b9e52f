"""Output folders that are the tool's own: every command with a folder --out writes only
into a new folder, an empty one, or one fruit made; a user's files are refused in one
line before anything is written, and stay byte for byte as they were."""

from __future__ import annotations

import json
import os

import click
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import COMMANDS, cli
from fruitcli.cli.options import OutFolder
from fruitcli.output_folder import MARKER, is_own
from tests.conftest import PAPER, ROOT

# command -> (its other arguments, the files it writes into --out)
OUTPUTS = {
    "run": (["s.toml"], ["pad-grid/taxels.csv", "tetra/mesh.npz", "evaluate/table.md"]),
    "demo": ([], ["report.md", "scenes/paper-table.toml", "paper-table/evaluate/table.md"]),
    "simulate": (
        ["s.toml"],
        ["mesh.npz", "mesh.msh", "quality.json", "states.npz", "yarns.csv", "pressure-check.npz"],
    ),
    "limits": (["s.toml"], ["mesh.npz", "limits.json", "pv.csv", "pv.png"]),
    "tetra": (["s.toml"], ["mesh.npz", "mesh.msh", "mesh.vtu", "quality.json"]),
    "skin": (["s.toml"], ["crossing.npz", "summary.json"]),
    "bench": (["s.toml"], ["small/frames.npz", "small/truth.csv"]),
    "locate": (["f.npz", "--taxels", "t.csv"], ["touches.csv", "measured.csv"]),
    "evaluate": (
        ["--truth", "t.csv", "--measured", "m.csv"],
        ["errors.csv", "table.md", "table.csv", "summary.json", "top.png", "side.png"],
    ),
    "calibrate": (
        ["f.npz", "--truth", "t.csv", "--scene", "s.toml"],
        ["skin.toml", "gains.csv", "calibration.json"],
    ),
    "make-tracks": (
        ["a.stl"],
        ["reduced.stl", "tracked_top.stl", "tracks.stl", "taxels.csv", "report.json"],
    ),
    "make-mold": (["s.toml"], ["mold.json", "preview.png"]),
    "study stability": ([], ["stability.md", "stability.csv", "stability.json"]),
    "study runtime": (["s.toml"], ["runtime.md", "runtime.json", "runtime.png"]),
    "study bench": (["s.toml"], ["bench.md", "bench.csv", "bench.json", "bench.png"]),
    "study locate": (["s.toml"], ["locate_methods.md", "locate_methods.csv", "locate_methods.png"]),
    "study two-fingers": ([], ["two_fingers.md", "two_fingers.csv", "single_fingers.csv"]),
    "study heights": ([], ["hover_heights.md", "hover_heights.csv"]),
    "sweep": (["s.toml"], ["sweep.csv", "sweep.md", "sweep.png"]),
}
CASES = [(cmd, name) for cmd, (_, names) in OUTPUTS.items() for name in names]


def _run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def _commands_with_an_out_folder():
    """Every (sub)command whose --out is a folder."""
    found = set()

    def walk(cmd: click.Command, path: str):
        if isinstance(cmd, click.Group):
            for name, sub in cmd.commands.items():
                walk(sub, f"{path} {name}")
        elif any(isinstance(p.type, OutFolder) for p in cmd.params if "--out" in p.opts):
            found.add(path)

    for name in COMMANDS:
        walk(cli.get_command(None, name), name)
    return found


def test_the_table_covers_every_command_with_an_out_folder():
    assert _commands_with_an_out_folder() == set(OUTPUTS)


def _tree(folder):
    return {
        p.relative_to(folder).as_posix(): p.read_bytes() for p in folder.rglob("*") if p.is_file()
    }


@pytest.mark.parametrize("command,name", CASES, ids=[f"{c}:{n}" for c, n in CASES])
def test_a_user_file_named_like_an_output_is_kept(tmp_path, command, name):
    out = tmp_path / "mine"
    (out / name).parent.mkdir(parents=True, exist_ok=True)
    (out / name).write_bytes(b"the user's own \x00\xff" + name.encode())
    before = _tree(out)
    args, _ = OUTPUTS[command]
    res = _run(*command.split(), *args, "--out", out)
    assert res.exit_code == 1, res.output
    assert res.output.splitlines() == [
        f"Error: --out {out}: holds files fruit did not write; choose a new folder or "
        "empty it (nothing written)"
    ]
    assert _tree(out) == before
    assert not (tmp_path / "s.toml").exists()  # nothing else either


@pytest.mark.parametrize("command", ["tetra", "evaluate", "demo", "study heights"])
def test_an_out_that_is_a_file_or_under_one_is_one_line(tmp_path, command):
    args, _ = OUTPUTS[command]
    blocker = tmp_path / "notes.txt"
    blocker.write_text("mine")
    res = _run(*command.split(), *args, "--out", blocker)
    assert res.exit_code == 1
    assert res.output.splitlines() == [
        f"Error: --out {blocker}: is a file, not a folder; choose a new folder (nothing written)"
    ]
    res = _run(*command.split(), *args, "--out", blocker / "out")
    assert res.exit_code == 1
    assert res.output.splitlines() == [
        f"Error: --out {blocker / 'out'}: {blocker} is a file, not a folder; choose another "
        "folder (nothing written)"
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]
    assert blocker.read_text() == "mine"


def test_an_unwritable_out_is_one_line(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    if os.access(locked, os.W_OK):
        pytest.skip("running as root: a mode-555 folder is still writable")
    res = _run("evaluate", "--truth", "t.csv", "--measured", "m.csv", "--out", locked)
    assert res.exit_code == 1
    assert res.output.splitlines() == [
        f"Error: --out {locked}: not writable; choose a folder you can write (nothing written)"
    ]
    res = _run("evaluate", "--truth", "t.csv", "--measured", "m.csv", "--out", locked / "o")
    assert res.exit_code == 1 and len(res.output.splitlines()) == 1
    assert "Permission denied" in res.output


def _evaluate(out):
    truth, measured = PAPER / "paper_rest_truth.csv", PAPER / "paper_rest_measured.csv"
    return _run("evaluate", "--truth", truth, "--measured", measured, "--out", out)


def test_new_empty_and_own_folders_are_written_and_marked(tmp_path):
    new = tmp_path / "a" / "b"
    assert _evaluate(new).exit_code == 0
    # the folders it made are its own: each holds the marker
    assert (new / MARKER).is_file() and (tmp_path / "a" / MARKER).is_file()
    assert json.loads((new / MARKER).read_text())["written_by"] == "fruit"
    assert not (tmp_path / MARKER).exists()  # a folder it did not make
    table = (new / "table.md").read_bytes()
    assert _evaluate(new).exit_code == 0 and (new / "table.md").read_bytes() == table
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / ".DS_Store").write_bytes(b"")
    assert _evaluate(empty).exit_code == 0 and (empty / "table.md").exists()
    # a folder made on the way is fruit's too
    assert is_own(tmp_path / "a")


def test_a_command_that_writes_nothing_leaves_no_folder(tmp_path):
    out = tmp_path / "x" / "y"
    res = _run("evaluate", "--truth", "no.csv", "--measured", "no.csv", "--out", out)
    assert res.exit_code == 1
    assert list(tmp_path.iterdir()) == []
    res = _run("run", ROOT / "pipelines" / "paper-table.toml", "--dry-run", "--out", out)
    assert res.exit_code == 0, res.output
    assert list(tmp_path.iterdir()) == []
    own = tmp_path / "own"
    assert _evaluate(own).exit_code == 0
    _run("evaluate", "--truth", "no.csv", "--measured", "no.csv", "--out", own)
    assert (own / MARKER).exists()  # an earlier run's folder stays fruit's


def test_a_run_folder_from_before_the_marker_is_recognised(tmp_path):
    """A `fruit run` or `fruit demo` folder written without the marker: its stage
    manifests say it is fruit's."""
    out = tmp_path / "out"
    (out / "paper-table" / "evaluate").mkdir(parents=True)
    manifest = {"stage": "evaluate", "hash": "0" * 64, "outputs": []}
    (out / "paper-table" / "evaluate" / "manifest.json").write_text(json.dumps(manifest))
    (out / "report.md").write_text("an earlier report")
    assert is_own(out) and is_own(out / "paper-table")
    res = _run("demo", "--scenes", "paper-table", "--out", out)
    assert res.exit_code == 0, res.output
    assert "Rest, small" in (out / "report.md").read_text()
    # a manifest of the user's own with other keys is no sign
    mine = tmp_path / "mine"
    (mine / "sub").mkdir(parents=True)
    (mine / "sub" / "manifest.json").write_text('{"name": "my package"}')
    assert not is_own(mine)


def test_a_default_out_is_claimed_as_a_given_one(tmp_path, monkeypatch):
    """`fruit run SCENE` writes into out/<scene name>: a folder of the user's there is
    refused too."""
    monkeypatch.chdir(tmp_path)
    scene = ROOT / "pipelines" / "paper-table.toml"
    mine = tmp_path / "out" / "paper-table"
    mine.mkdir(parents=True)
    (mine / "evaluate").write_text("my notes\n")
    res = _run("run", scene)
    assert res.exit_code == 1
    assert res.output.splitlines() == [
        "Error: --out out/paper-table: holds files fruit did not write; choose a new folder "
        "or empty it (nothing written)"
    ]
    assert (mine / "evaluate").read_text() == "my notes\n"
    (mine / "evaluate").unlink()
    res = _run("run", scene)
    assert res.exit_code == 0, res.output
    assert (mine / "evaluate" / "table.md").exists() and (mine / MARKER).exists()
