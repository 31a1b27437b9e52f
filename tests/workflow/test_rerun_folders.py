"""A rerun leaves exactly what a fresh run would: a stage that runs again clears its
earlier outputs, a stage whose outputs changed since they were written runs again (here
or in the sibling folder it would be copied from), and no stage writes through a link
out of the output folder."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.output_folder import MARKER
from fruitcli.scene import parse_scene
from fruitcli.workflow import planner
from tests.compare_runs import compare

# a flat pad on the virtual bench, no FEM: pad-grid, bench, locate, evaluate in seconds
SCENE = """
[scene]
name = "rerun"
configuration = "{configuration}"
[geometry]
pad_size_mm = [40.0, 40.0, 3.0]
[grid]
count = [3, 3]
spacing_x_mm = 12.0
spacing_y_mm = 12.0
[bench]
indenters = {indenters}
"""
BEFORE = {"configuration": "Rest", "indenters": '["small", "medium"]'}
AFTER = {"configuration": "Bent", "indenters": '["small"]'}


def _scene(folder, values):
    path = folder / "s.toml"
    path.write_text(SCENE.format(**values))
    return parse_scene(path.read_text(), path)


def _actions(steps):
    return {s.stage: s.action for s in steps if s.action != "not needed"}


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    """Fresh runs of the scene before and after the edit, each alone under its parent."""
    out = {}
    for name, values in (("before", BEFORE), ("after", AFTER)):
        root = tmp_path_factory.mktemp(name)
        planner.run(_scene(root, values), root / "out")
        out[name] = root / "out"
    return out


def test_renaming_an_evaluation_and_dropping_an_indenter_leaves_no_old_folder(fresh, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(fresh["before"], out)
    steps = planner.run(_scene(tmp_path, AFTER), out)
    assert _actions(steps) == {
        "pad-grid": "reuse",
        "bench": "run",
        "locate": "run",
        "evaluate": "run",
    }
    for gone in ("bench/medium", "locate/medium", "evaluate/rest-small", "evaluate/rest-medium"):
        assert not (out / gone).exists(), gone
    assert (out / "evaluate" / "bent-small" / "errors.csv").exists()
    assert compare(fresh["after"], out) == []
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []  # no temporary


def _edit(out):
    """The user's edits of two outputs: a taxel moved, a recording cut short."""
    taxels = out / "pad-grid" / "taxels.csv"
    taxels.write_text(taxels.read_text().replace("12.000000", "13.000000", 1))
    frames = out / "bench" / "small" / "frames.npz"
    frames.write_bytes(frames.read_bytes()[:1000])


def test_changed_outputs_are_run_again_with_one_line_naming_the_file(fresh, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(fresh["after"], out)
    (out / MARKER).write_text("{}\n")
    _edit(out)
    _scene(tmp_path, AFTER)
    res = CliRunner().invoke(cli, ["run", str(tmp_path / "s.toml"), "--out", str(out)])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert any(
        line.endswith(
            f"pad-grid: {out}/pad-grid/taxels.csv changed since it was written: run again"
        )
        for line in lines
    ), res.output
    assert any(
        line.endswith(
            f"bench: {out}/bench/small/frames.npz changed since it was written: run again"
        )
        for line in lines
    ), res.output
    # the taxels came out as before, so what follows the bench is taken as it is
    assert "locate       reuse" in res.output and "evaluate     reuse" in res.output
    (out / MARKER).unlink()  # (the fresh run ran without the command line)
    assert compare(fresh["after"], out) == []
    # the plan says it too, and then nothing is left to do
    steps = planner.plan(_scene(tmp_path, AFTER), out)
    assert set(_actions(steps).values()) == {"reuse"}


def test_a_dry_run_names_the_changed_output(fresh, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(fresh["after"], out)
    (out / "evaluate" / "table.md").write_text("my own table\n")
    steps = {s.stage: s for s in planner.plan(_scene(tmp_path, AFTER), out)}
    assert steps["evaluate"].action == "run"
    assert steps["evaluate"].reason.endswith("; rerun: table.md changed since it was written")
    (out / "evaluate" / "table.md").unlink()
    steps = {s.stage: s for s in planner.plan(_scene(tmp_path, AFTER), out)}
    assert steps["evaluate"].reason.endswith("; rerun: table.md is missing")


def test_a_sibling_whose_outputs_changed_lends_nothing_changed(fresh, tmp_path):
    sibling = tmp_path / "a"
    shutil.copytree(fresh["after"], sibling)
    _edit(sibling)
    said = []
    steps = planner.run(
        _scene(tmp_path, AFTER), tmp_path / "b", progress=said.append, shared=tmp_path
    )
    acts = _actions(steps)
    assert acts["pad-grid"] == "run" and acts["bench"] == "run"
    changed = f"{sibling}/pad-grid/taxels.csv changed since it was written"
    assert f"pad-grid: {changed}: not copied from there" in said
    assert {s.stage: s.reason for s in steps}["locate"].endswith("(same inputs as a)")
    assert compare(fresh["after"], tmp_path / "b") == []


def test_a_stage_folder_linked_out_of_the_output_folder_is_refused(fresh, tmp_path):
    mine = tmp_path / "my-notes"
    mine.mkdir()
    (mine / "table.md").write_text("my table\n")
    out = tmp_path / "out"
    shutil.copytree(fresh["after"], out)
    (out / MARKER).write_text("{}\n")
    shutil.rmtree(out / "evaluate")
    (out / "evaluate").symlink_to(mine, target_is_directory=True)
    _scene(tmp_path, AFTER)
    res = CliRunner().invoke(cli, ["-q", "run", str(tmp_path / "s.toml"), "--out", str(out)])
    assert res.exit_code == 1
    assert res.output.splitlines() == [
        f"Error: {out}/evaluate: a symbolic link to {mine}, outside {out}; fruit writes only "
        "inside its output folder: remove the link or choose another --out"
    ]
    assert sorted(p.name for p in mine.iterdir()) == ["table.md"]
    assert (mine / "table.md").read_text() == "my table\n"
    # a link that stays inside the output folder is replaced by the stage's own folder
    (out / "evaluate").unlink()
    (out / "evaluate").symlink_to(out / "locate", target_is_directory=True)
    res = CliRunner().invoke(cli, ["-q", "run", str(tmp_path / "s.toml"), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert not (out / "evaluate").is_symlink() and (out / "locate" / "small").is_dir()
    (out / MARKER).unlink()
    assert compare(fresh["after"], out) == []


def test_the_manifest_holds_each_output_s_sha256(fresh):
    import hashlib
    import json

    manifest = json.loads((fresh["after"] / "bench" / "manifest.json").read_text())
    assert sorted(manifest["files"]) == ["small/frames.npz", "small/truth.csv"]
    data = (fresh["after"] / "bench" / "small" / "frames.npz").read_bytes()
    assert manifest["files"]["small/frames.npz"] == hashlib.sha256(data).hexdigest()
    assert np.load(fresh["after"] / "bench" / "small" / "frames.npz")["frames"].ndim == 3


def test_a_stage_that_fails_on_a_rerun_keeps_its_earlier_folder_whole(tmp_path):
    from tests.conftest import PAPER

    measured = tmp_path / "m.csv"
    measured.write_text((PAPER / "paper_rest_measured.csv").read_text())
    text = (
        f'[[evaluate]]\nlabel = "Rest, small"\ntruth = "{PAPER / "paper_rest_truth.csv"}"\n'
        f'measured = "{measured}"\n'
    )
    scene = parse_scene(text, tmp_path / "s.toml")
    out = tmp_path / "out"
    planner.run(scene, out)
    before = {p: p.read_bytes() for p in (out / "evaluate").rglob("*") if p.is_file()}
    measured.write_text("sample,x_mm\n1,2\n")  # no y column: the evaluation fails
    with pytest.raises(Exception, match="m.csv"):
        planner.run(scene, out)
    after = {p: p.read_bytes() for p in (out / "evaluate").rglob("*") if p.is_file()}
    assert after == before
    assert [p.name for p in out.iterdir()] == ["evaluate"]  # no temporary folder left
    assert _actions(planner.plan(scene, out)) == {"evaluate": "run"}
