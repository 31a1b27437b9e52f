"""The stage planner: needed stages, reasons, reuse by content hash, `fruit run`."""

from __future__ import annotations

from pathlib import Path

from fruitcli.scene import parse_scene
from fruitcli.workflow import planner
from fruitcli.workflow.planner import Stage
from tests.conftest import PAPER


def _scene(tmp_path, extra=""):
    text = f"""
[[evaluate]]
label = "Rest, small"
truth = "{PAPER / "paper_rest_truth.csv"}"
measured = "{tmp_path / "m.csv"}"
reference_length_mm = 152.0
{extra}"""
    (tmp_path / "m.csv").write_text((PAPER / "paper_rest_measured.csv").read_text())
    return parse_scene(text, tmp_path / "s.toml")


def _actions(steps):
    return {s.stage: s.action for s in steps}


def test_evaluation_only_plan(tmp_path):
    steps = planner.plan(_scene(tmp_path), tmp_path / "out")
    acts = _actions(steps)
    assert acts["evaluate"] == "run"
    assert all(a == "not needed" for k, a in acts.items() if k != "evaluate")
    reasons = {s.stage: s.reason for s in steps}
    assert reasons["simulate"] == "no deformation: taxels at rest, no FEM"
    assert reasons["evaluate"] == "evaluation only: measured points given"


def test_reuse_until_an_input_changes(tmp_path):
    sc = _scene(tmp_path)
    out = tmp_path / "out"
    assert _actions(planner.run(sc, out))["evaluate"] == "run"
    assert _actions(planner.plan(sc, out))["evaluate"] == "reuse"
    assert _actions(planner.run(sc, out))["evaluate"] == "reuse"
    # a changed input file reruns the stage
    (tmp_path / "m.csv").write_text((tmp_path / "m.csv").read_text().replace("-4.41", "-4.40"))
    assert _actions(planner.plan(sc, out))["evaluate"] == "run"
    planner.run(sc, out)
    # a changed parameter too
    sc2 = parse_scene(
        f"""[[evaluate]]
label = "Rest, small"
truth = "{PAPER / "paper_rest_truth.csv"}"
measured = "{tmp_path / "m.csv"}"
reference_length_mm = 150.0
""",
        tmp_path / "s.toml",
    )
    assert _actions(planner.plan(sc2, out))["evaluate"] == "run"


def test_deleted_output_reruns(tmp_path):
    sc = _scene(tmp_path)
    out = tmp_path / "out"
    planner.run(sc, out)
    (out / "evaluate" / "table.md").unlink()
    assert _actions(planner.plan(sc, out))["evaluate"] == "run"


def test_dry_run_cli(fruit, tmp_path):
    from tests.conftest import ROOT

    res = fruit(
        "run", ROOT / "pipelines" / "paper-table.toml", "--dry-run", "--out", tmp_path / "o"
    )
    assert res.exit_code == 0
    assert "evaluate     run" in res.output
    assert "no deformation: taxels at rest, no FEM" in res.output
    assert not (tmp_path / "o").exists()
    res = fruit(
        "run",
        ROOT / "pipelines" / "paper-table.toml",
        "--dry-run",
        "--until",
        "make-tracks",
        "--out",
        tmp_path / "o",
    )
    assert res.exit_code == 0 and "make-tracks" in res.output
    assert "evaluate" not in res.output and "locate" not in res.output
    res = fruit(
        "run",
        ROOT / "pipelines" / "paper-table.toml",
        "--dry-run",
        "--until",
        "bogus",
        "--out",
        tmp_path / "o",
    )
    assert res.exit_code == 1 and "unknown stage 'bogus'" in res.output


def test_run_bad_scene_is_one_line(fruit, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[material]\nyoung_modulus = 3\n")
    res = fruit("run", bad)
    assert res.exit_code == 1
    assert "unknown key 'young_modulus' (did you mean 'young_modulus_kpa'?)" in res.output


def test_fruit_help_lists_stages(fruit):
    res = fruit("--help")
    assert res.exit_code == 0
    for name in ("run", "make-tracks", "simulate", "locate", "evaluate"):
        assert name in res.output
    assert Path  # keep import used


def test_identical_stage_is_borrowed_from_a_sibling_scene(tmp_path):
    sc = _scene(tmp_path)
    planner.run(sc, tmp_path / "out" / "first", shared=tmp_path / "out")
    steps = planner.run(sc, tmp_path / "out" / "second", shared=tmp_path / "out")
    step = [s for s in steps if s.stage == "evaluate"][0]
    assert step.action == "reuse" and "same inputs as first" in step.reason
    assert (tmp_path / "out" / "second" / "evaluate" / "table.md").read_text() == (
        tmp_path / "out" / "first" / "evaluate" / "table.md"
    ).read_text()


def test_plan_shows_stages_copied_from_a_sibling_and_judges_the_next_on_them(tmp_path):
    """Stage b reads stage a's output file. After a run for scene 'first', the plan for
    'second' (with the same inputs) says both are copied from 'first', not run: b's input
    is judged on the file it would be copied with."""

    def yes(scene):
        return True, "always"

    def write(name):
        def run(scene, ctx, out_dir):
            out_dir.mkdir(parents=True, exist_ok=True)
            (out_dir / f"{name}.txt").write_text(name)
            return {}

        return run

    a = Stage(
        "a",
        [],
        "fruitcli.geometry.padgrid",
        yes,
        lambda s, c: {"k": 1},
        write("a"),
        lambda s: ["a.txt"],
    )
    b = Stage(
        "b",
        ["a"],
        "fruitcli.geometry.padgrid",
        yes,
        lambda s, c: {"a": c.dir("a") / "a.txt"},
        write("b"),
        lambda s: ["b.txt"],
    )
    sc, out = _scene(tmp_path), tmp_path / "out"
    planner.run(sc, out / "first", stages=[a, b])
    steps = planner.plan(sc, out / "second", stages=[a, b], shared=out)
    assert [(st.stage, st.action) for st in steps] == [("a", "reuse"), ("b", "reuse")]
    assert all("same inputs as first" in st.reason for st in steps)
    assert not (out / "second").exists()
    assert [st.action for st in planner.plan(sc, out / "second", stages=[a, b])] == ["run"] * 2


def test_every_subcommand_has_help_with_units(fruit):
    from fruitcli.cli.main import COMMANDS

    for name in COMMANDS:
        res = fruit(name, "--help")
        assert res.exit_code == 0, (name, res.output)
        assert "None]" not in res.output, (name, res.output)  # no 'x<=None' for a range
    for name in ("make-tracks", "simulate", "locate", "evaluate", "bench", "record"):
        res = fruit(name, "--help")
        assert "mm" in res.output or "counts" in res.output or "frames" in res.output, name


def test_bench_samples_csv_is_hashed_by_content(tmp_path):
    """A bench's sample CSV is an input by its content: two scenes naming different
    files 'pts.csv' get different bench hashes (so one is never copied for the other),
    and editing the file reruns the stage."""
    from fruitcli.workflow.stages import STAGES

    bench = next(s for s in STAGES if s.name == "bench")
    hashes = []
    for n, rows in enumerate(["0,1.0,2.0\n", "0,5.0,2.0\n", "0,5.0,2.0\n"]):
        d = tmp_path / f"s{n}"
        d.mkdir()
        (d / "pts.csv").write_text("sample,x_mm,y_mm\n" + rows)
        (d / "t.csv").write_text("id,i,j,x_mm,y_mm,z_mm\n0,0,0,0,0,0\n")
        text = '[grid]\ntaxels = "t.csv"\n[bench]\nsamples = "pts.csv"\n'
        scene = parse_scene(text, d / "s.toml")
        hashes.append(planner.fingerprint(bench, scene, planner.Context(d / "out")))
    assert hashes[0] != hashes[1] and hashes[1] == hashes[2]


def test_stage_code_hash_covers_the_packages_it_imports():
    """The FEM stages' hash covers fruitcli/fem with its subpackages and what it
    imports (geometry/mesh/load.py for the unit check, the scene package), so a change there reruns
    them; evaluation's does not cover the FEM."""
    files = {f"{p.parent.name}/{p.name}" for p in planner.code_files("fruitcli.fem.stage")}
    assert {
        "fem/stage.py",
        "materials/corotation_kernels.py",
        "elements/integrate.py",
        "solver/newton.py",
        "mesh/load.py",
        "scene/schema.py",
        "scene/records.py",
    } <= files
    files = {p.parent.name for p in planner.code_files("fruitcli.evaluation.report")}
    assert "fem" not in files and "evaluation" in files


def test_a_scene_copied_elsewhere_keeps_the_stages_after_make_artist(tmp_path):
    """`fruit demo` runs its own copy of a bundled scene (OUT/scenes/) into the folder a
    tutorial's copy ran into: make-artist runs again only because its mesh is missing at
    the new path, and the mesh it writes gives make-tracks the same hash as before."""
    from fruitcli import bundled
    from fruitcli.scene import load_scene

    out = tmp_path / "out" / "fruit-rest"
    first = load_scene(bundled.export_scene("fruit-rest", tmp_path / "rest"))
    planner.run(first, out, until="make-artist")
    second = load_scene(bundled.export_scene("fruit-rest", tmp_path / "out" / "scenes"))
    moved = planner.plan(second, out, until="make-tracks")
    assert [(s.stage, s.action) for s in moved] == [("make-artist", "run"), ("make-tracks", "run")]
    assert "fruit_artist.ply is missing" in moved[0].reason
    planner.run(second, out, until="make-artist")
    again = planner.plan(first, out, until="make-tracks")
    assert _actions(again)["make-artist"] == "reuse"
    assert [s.hash for s in planner.plan(second, out, until="make-tracks")] == [
        s.hash for s in again
    ]
    assert (tmp_path / "rest" / "fruit_artist.ply").read_bytes() == (
        tmp_path / "out" / "scenes" / "fruit_artist.ply"
    ).read_bytes()


def test_run_prints_the_plan_once(fruit, tmp_path):
    """While running, a line per stage that runs or is reused; at the end the plan, with
    the stages not needed, once."""
    from tests.conftest import ROOT

    res = fruit("run", ROOT / "pipelines" / "paper-table.toml", "--out", tmp_path / "o")
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert [line for line in lines if "make-artist" in line] == [
        "make-artist  not needed      no geometry: evaluation only"
    ]
    assert len([line for line in lines if "evaluate" in line]) == 2  # progress, plan
    assert lines[-13] == f"paper-table: done -> {tmp_path / 'o'}/"
