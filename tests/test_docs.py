"""The documentation against the code: the generated reference covers every command and
scene key, the performance page shows a bench result's figures, every TOML example is a
valid scene, and every tutorial's command list runs on the bundled data (at smaller mesh
sizes where a step would take minutes). The site's build itself (warnings as errors,
internal links checked) is `make docs`, a step of .ci/run."""

from __future__ import annotations

import importlib.util
import os
import re
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from fruitcli.cli.main import COMMANDS
from fruitcli.scene import ARRAY_SCHEMA, SCHEMA, parse_scene

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


generate = load(DOCS / "generate.py", "docs_generate")
RUN_ALL = ROOT / "tests" / "performance" / "run_all.py"
run_all = load(RUN_ALL, "bench_run_all")


def test_cli_page_has_every_command_and_option():
    page = generate.cli_page()
    for name in COMMANDS:
        assert f"\n## fruit {name}\n" in page
    for sub in (
        "fruit scenes copy",
        "fruit study runtime",
        "fruit study stability",
        "fruit study bench",
    ):
        assert f"\n## {sub}\n" in page
    run_section = page.split("\n## fruit run\n")[1].split("\n## ")[0]
    for option in ("--out DIRECTORY", "--dry-run", "--until TEXT", "--force"):
        assert f"- `{option}`" in run_section
    assert "- `SCENE`" in run_section


def test_cli_page_shows_the_help_option_and_options_in_text_as_code():
    """`-h, --help` as the CLI has it; an option named in a help text is a code span
    (Sphinx would turn the two hyphens of a bare --out into an en dash)."""
    page = generate.cli_page()
    assert re.search(r"\n  -h, --help +Show this message and exit\.", page)
    assert "- `--overwrite`: Replace an existing `--out` file." in page
    bare, fenced = [], False
    for line in page.splitlines():
        fenced = fenced != line.startswith("```")
        text = re.sub(r"`[^`]*`", "", line)  # outside code spans
        if not fenced and re.search(r"(?<![\w-])--[a-z]", text):
            bare.append(line)
    assert bare == []
    assert generate.escape("give --out or -v; a - b -- c") == "give `--out` or -v; a - b -- c"


def test_solvers_section_is_a_table_of_the_bench_rows():
    info = {
        "date": "2026-12-06T04:30:00+00:00",
        "commit": "0123456789abcdef",
        "machine": "a CPU, 2 cores",
        "load_average_before": [1.0, 2.0, 3.0],
        "load_average_after": [4.0, 5.0, 6.0],
        "scene": "pipelines/fruit-breathing.toml",
        "rows": [
            {"what": "MKL PARDISO", "wall_s": 68.1, "solve_s": 44.9, "states": 13,
             "newton_iterations": 30, "max_node_difference_mm": 0.0},
            {"what": "cholespy_x", "wall_s": 600.4, "solve_s": 570.0, "states": 13,
             "newton_iterations": 31, "max_node_difference_mm": 2.6e-7},
        ],
    }  # fmt: skip
    section = generate.solvers_section(info)
    assert section.startswith("## With and without PARDISO\n")
    assert "| MKL PARDISO | 68 | 45 | 13 | 30 | 0 |" in section
    assert "| cholespy\\_x | 600 | 570 | 13 | 31 | 3e-07 |" in section
    assert "load average 1.00, 2.00, 3.00 before, 4.00, 5.00, 6.00 after" in section
    assert "commit `0123456789ab`" in section
    assert "--refusals" not in section
    info["refusals"] = [
        {"what": "MKL PARDISO", "c1_kpa": -500.0, "after_mesh_s": 31.5, "exit_code": 1,
         "same_line": True},
        {"what": "default", "c1_kpa": 2000.0, "after_mesh_s": 64.1, "exit_code": 1,
         "same_line": False},
    ]  # fmt: skip
    section = generate.solvers_section(info)
    assert "| MKL PARDISO | -500 kPa | 32 | 1 | yes |" in section
    assert "| default | 2000 kPa | 64 | 1 | no |" in section
    assert "bench_linear_solver.py --refusals --docs` on a CPU" in section


def test_scene_page_has_every_key_with_its_unit_and_default():
    page = generate.scene_page()
    rows = {}
    for line in page.splitlines():
        cells = [c.strip() for c in line.split(" | ")]
        if line.startswith("| `") and len(cells) == 5:
            rows.setdefault(cells[0].strip("|` "), []).append(cells)
    for spec in [*SCHEMA.values(), *ARRAY_SCHEMA.values()]:
        for key in spec:
            assert key in rows, key
    young = rows["young_modulus_kpa"][0]
    assert young[1:4] == ["number, 0 < value ≤ 1e+09", "`100.0`", "kPa"]
    assert rows["vector_m_s2"][0][2:4] == ["`[0.0, 0.0, -9.81]`", "m/s²"]
    assert rows["stiffness_n_per_mm"][0][3] == "N/mm"
    assert rows["box_mm"][0][2] == "`required`"
    assert rows["element"][0][1] == "text: one of `p2`, `p2-pure`, `p1`"
    assert rows["poisson_ratio"][0][1] == "number, -1 < value < 0.5"
    assert "## \\[\\[evaluate\\]\\] (at most 1,000 tables)" in page
    assert rows["indenters"][0][1].endswith(", at most 64 entries")


def test_bench_lines_split_into_template_and_numbers():
    assert run_all.split_line("p1 state: median 7.6 ms (runs 7.4-8.1), 1,520,000 frames/s") == (
        "p1 state: median {} ms (runs {}-{}), {} frames/s",
        [7.6, 7.4, 8.1, 1520000.0],
    )
    assert run_all.split_line("bench_fem p2 4x4 8N1 100k {x}") == (
        "bench_fem p2 4x4 8N1 100k {{x}}",
        [],
    )


def test_bench_figures_are_min_median_max_over_runs():
    outputs = [
        "a: 1.0 ms, 5 MB\nb: 2\nb: 7\n",
        "a: 3.0 ms, 5 MB\nb: 4\nb: 9\n",
        "a: 8.0 ms, 5 MB\nb: 3\n",
    ]
    figures = run_all.figures(outputs)
    assert [(f["line"], f["occurrence"], f["runs"]) for f in figures] == [
        ("a: {} ms, {} MB", 0, 3),
        ("b: {}", 0, 3),
        ("b: {}", 1, 2),
    ]
    a_ms = figures[0]["numbers"][0]
    assert (a_ms["min"], a_ms["median"], a_ms["max"]) == (1.0, 3.0, 8.0)
    assert figures[2]["numbers"][0]["median"] == 8.0
    result = {
        "date": "2026-01-01T00:00:00+00:00",
        "commit": "abc",
        "cores": 2,
        "processor": "CPU <x>",
        "runs": 3,
        "load_average_before": [1.0, 0.5, 0.25],
        "load_average_after": [2.0, 1.0, 0.5],
        "scripts": [
            {
                "name": "bench_x",
                "exit_codes": [0, 0, 0],
                "figures": figures,
                "wall_s": {"min": 1.0, "median": 2.0, "max": 4.0},
            }
        ],
    }
    page = generate.performance_page(result, "build/bench/bench.json")
    assert "a: 3 ms, 5 MB\nb: 3\nb: 8\n" in page
    assert "| a: \\# ms, \\# MB | 1 | 1 | 3 | 8 |" in page
    assert (
        "| processor | CPU \\<x\\> |" in page
        and "| load average before (1, 5, 15 min) | 1.00, 0.50, 0.25 |" in page
    )
    assert "wall time 2 s (min 1, max 4)" in page


def test_run_all_writes_a_result_file(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    res = subprocess.run(
        [
            sys.executable,
            str(RUN_ALL),
            "--only",
            "bench_evaluate",
            "--json",
            str(tmp_path / "r.json"),
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr
    import json

    result = json.loads((tmp_path / "r.json").read_text())
    assert result["cores"] == os.cpu_count() and result["runs"] == 1
    assert len(result["load_average_before"]) == 3
    (script,) = result["scripts"]
    assert script["name"] == "bench_evaluate" and script["exit_codes"] == [0]
    assert script["figures"][0]["line"].startswith("summarize 100k samples: {} ms")
    page = generate.performance_page(result, str(tmp_path / "r.json"))
    assert "## bench_evaluate" in page
    res = subprocess.run(
        [sys.executable, str(RUN_ALL), "--only", "bench_nothing"],
        env=env,
        capture_output=True,
        text=True,
    )
    assert res.returncode == 2 and "--only: no script bench_nothing" in res.stderr


def test_every_toml_example_in_the_docs_is_a_valid_scene():
    pages = sorted(DOCS.rglob("*.md")) + [ROOT / "README.md"]
    checked = 0
    for page in pages:
        if "_generated" in page.parts:
            continue
        for block in re.findall(r"```toml\n(.*?)```", page.read_text(), re.S):
            parse_scene(block, ROOT / "pipelines" / "example.toml", must_exist=False)
            checked += 1
    assert checked >= 3


# ------------------------------------------------------------------------------ tutorials
def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# Per tutorial: (text in its command list, what the test runs instead). Each text must be
# there, so a tutorial that changes is noticed here.
SMALLER = {
    "fruit-to-table-1": [
        (
            "fruit scenes copy fruit-deformed deformed\n",
            "fruit scenes copy fruit-deformed deformed\n"
            "sed -i 's/^size_mm = 5.0/size_mm = 8.0/' deformed/fruit-deformed.toml\n",
        ),
        ("--scenes paper-table,fruit-rest,fruit-deformed", "--scenes paper-table,fruit-rest"),
    ],
    "own-sculpture": [("[mesh]\nsize_mm = 6.0", "[mesh]\nsize_mm = 8.0")],
    "lab": [],
    "installation": [("--view 8765", "--view {port}")],
}
EXPECTED = {  # files the tutorial's page says its commands make
    "fruit-to-table-1": [
        "out/paper-table/evaluate/table.md",
        "out/fruit-rest/evaluate/table.md",
        "out/fruit-deformed/evaluate/deformed-small/top.png",
        "out/report.md",
    ],
    "own-sculpture": [
        "tracks/taxels.csv",
        "tracks/preview.png",
        "out/sculpture/simulate/yarns.csv",
        "out/sculpture/evaluate/table.md",
        "molds/mold.json",
    ],
    "lab": [
        "out/lab-bench/small/frames.npz",
        "out/lab-evaluate/table.md",
        "out/calibration/skin.toml",
        "out/width/skin.toml",
        "out/bench-calibrated/small/frames.npz",
        "recording.npz",
        "out/recording-locate/touches.csv",
    ],
    "installation": ["touches.jsonl", "fruit.log"],
}


def tutorial_script(name: str) -> str:
    text = (DOCS / "tutorials" / f"{name}.md").read_text()
    script = "\n".join(re.findall(r"```shell\n(.*?)```", text, re.S))
    assert script.strip(), f"{name}: no shell block"
    for old, new in SMALLER[name]:
        assert old in script, (name, old)
        script = script.replace(old, new.format(port=free_port()))
    return "set -euo pipefail\n" + script


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SMALLER))
def test_tutorial_commands_run(name, tmp_path):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    shim = bin_dir / "fruit"  # this checkout's fruit, whatever the venv has installed
    shim.write_text(
        f"#!/bin/sh\nexec {sys.executable} -c "
        "'import sys; from fruitcli.cli.main import main; sys.exit(main())' \"$@\"\n"
    )
    shim.chmod(0o755)
    work = tmp_path / "work"
    work.mkdir()
    env = {
        **os.environ,
        "PATH": f"{bin_dir}:{os.environ['PATH']}",
        "PYTHONPATH": str(ROOT),
        "MPLBACKEND": "Agg",
    }
    res = subprocess.run(
        ["bash", "-c", tutorial_script(name)],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    for rel in EXPECTED[name]:
        assert (work / rel).is_file() and (work / rel).stat().st_size > 0, rel
    made = {p.name for p in work.iterdir()}
    for rel in named_paths(name):  # what the page's prose names among what it made
        if rel.split("/")[0] in made:
            assert (work / rel).exists(), rel
    if name == "fruit-to-table-1":
        claims_of_tutorial_1(work, res.stdout, bin_dir / "fruit", env)
    if name == "own-sculpture":
        claims_of_tutorial_2(work, res.stdout)
    if name == "lab":
        claims_of_tutorial_3(work)
    if name == "installation":
        assert '"touches": [{"touch": 0' in (work / "touches.jsonl").read_text()
        assert " down 0 " in (work / "fruit.log").read_text()


def named_paths(name: str) -> list[str]:
    """Paths a tutorial's prose names in code spans (no placeholders such as <indenter>)."""
    text = (DOCS / "tutorials" / f"{name}.md").read_text()
    prose = re.sub(r"```.*?```", "", text, flags=re.S)
    return [p for p in re.findall(r"`([^`\s]+)`", prose) if "/" in p and "<" not in p]


def _plan(text: str) -> dict[str, str]:
    """stage -> action of a printed plan (its lines `name  action  reason`)."""
    return dict(re.findall(r"^([a-z-]+) +(run|reuse|not needed) ", text, re.M))


def claims_of_tutorial_2(work: Path, stdout: str) -> None:
    """What tutorial 2 says of its runs."""
    # make-tracks' outputs, as the page lists them
    for name in ("reduced.stl", "tracked_top.stl", "tracks.stl", "tracks.csv", "report.json"):
        assert (work / "tracks" / name).is_file(), name
    # "The planner runs make-tracks, tetra, simulate (three states, ...), the bench,
    # locate, evaluate and the sensitivity stage" (the dry run's plan)
    dry = stdout.split("plan for sculpture.toml -> out/sculpture/", 1)[1]
    plan = _plan(dry.split("\n\n", 1)[0])
    runs = ["make-tracks", "tetra", "simulate", "bench", "locate", "evaluate", "sensitivity"]
    assert [stage for stage, action in plan.items() if action == "run"] == runs, dry
    import numpy as np

    with np.load(work / "out/sculpture/simulate/states.npz") as states:
        assert states["taxels_mm"].shape[0] == 3
    # yarns.csv: per track its rest length and its largest stretch
    header = (work / "out/sculpture/simulate/yarns.csv").read_text().splitlines()
    columns = next(line for line in header if not line.startswith("#")).split(",")
    assert "track" in columns and any("rest" in c for c in columns), columns
    assert any("stretch" in c for c in columns), columns
    # "mold.json gives volumes and the silicone to mix"
    mold = (work / "molds" / "mold.json").read_text()
    assert "volume" in mold and "silicone" in mold


def claims_of_tutorial_3(work: Path) -> None:
    """What tutorial 3 says of its runs."""
    import numpy as np

    # "`--until pad-grid` makes the taxels only"
    assert (work / "out/pad/pad-grid/taxels.csv").is_file()
    assert not (work / "out/pad/tetra").exists() and not (work / "out/pad/simulate").exists()
    # "frames.npz (with the printer position of every frame) and truth.csv"
    with np.load(work / "out/lab-bench/small/frames.npz") as bench:
        assert len(bench["printer_mm"]) == len(bench["frames"]) > 0
    assert (work / "out/lab-bench/small/truth.csv").is_file()
    # skin.toml: "the footprint width, the activation at contact, the gap decay, a gain
    # per taxel and the noise", as a [skin] table
    skin = (work / "out/calibration/skin.toml").read_text()
    assert re.search(r"^\[skin\]$", skin, re.M), skin
    for key in ("footprint_sigma_mm", "contact_counts", "gap_decay_mm", "noise_std_counts"):
        assert key in skin, key
    assert (work / "out/calibration/gains.csv").is_file()
    # "fruit record ... --frames 200"
    with np.load(work / "recording.npz") as recording:
        assert len(recording["frames"]) == 200


def claims_of_tutorial_1(work: Path, stdout: str, fruit: Path, env: dict) -> None:
    """What tutorial 1 says of its runs (a stage "reused" or "taken over" is one the
    planner reports as reuse)."""
    out = work / "out"
    table = (out / "paper-table" / "evaluate" / "table.md").read_text()
    # "29 samples at rest, 2.56 mm mean error (1.7 % of 152 mm) and 1.28 mm standard
    # deviation"; "that row is a 2D error (3.81 mm)"
    assert "| Rest, small | 29 | 3D | none | 2.56 mm (1.7 %) | 1.28 mm (0.8 %) |" in table
    assert "| Deformed, small (top view) | 29 | top view (x, y) | none | 3.81 mm " in table
    # "the 3D row has side.png too": the top view's has not
    assert not (out / "paper-table/evaluate/deformed-small-top-view/side.png").exists()
    # "--dry-run prints the plan: make-artist writes the default Fruit ...; there is no FEM"
    dry = stdout.split("plan for rest/fruit-rest.toml -> out/fruit-rest/", 1)[1]
    plan = _plan(dry.split("done ->", 1)[0])
    assert plan["make-artist"] == "run" and plan["tetra"] == "not needed", dry
    # "make-artist runs once more ... every other stage that ran above is reused ...
    # except the demo's own stage model-rows"
    report = (out / "report.md").read_text()
    ran = re.findall(r"^([a-z-]+) +run ", report, re.M)
    assert ran.count("make-artist") == 1 and set(ran) == {"make-artist", "model-rows"}, report
    # "Run the last command again: every stage is reused" (after the demo too)
    again = subprocess.run(
        [str(fruit), "run", "rest/fruit-rest.toml", "--out", "out/fruit-rest", "--dry-run"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "run" not in _plan(again).values() and _plan(again)["bench"] == "reuse", again


def test_every_file_path_the_docs_name_exists():
    """Paths in `code spans` that name a source file or folder (fruitcli/..., tests/...,
    docs/..., a .py file) exist, so a moved module is noticed here."""
    pattern = re.compile(r"`((?:fruitcli|tests|docs)/[\w/.-]*|[\w/-]+\.py)`")
    named = set()
    for page in [*DOCS.rglob("*.md"), ROOT / "README.md"]:
        if "_generated" not in page.parts:
            named.update(pattern.findall(page.read_text()))
    assert len(named) >= 10
    missing = sorted(p for p in named if not (ROOT / p).exists())
    assert missing == []


def howto_commands() -> list[tuple[str, list[str]]]:
    """(page, argv) of every `fruit` command in the how-to pages' code blocks (lines
    continued with a backslash joined, comments dropped)."""
    import shlex

    found = []
    for page in sorted((DOCS / "howto").glob("*.md")):
        for block in re.findall(r"```(?:sh|shell)\n(.*?)```", page.read_text(), re.S):
            for line in block.replace("\\\n", " ").splitlines():
                argv = shlex.split(line, comments=True)
                if argv and argv[0] == "fruit":
                    found.append((page.name, argv[1:]))
    return found


def test_howto_commands_name_real_commands_and_options():
    """The how-tos are templates (SCENE, T.csv, PORT stand for the reader's files), so
    they are not run; every command and option they write exists, as the CLI spells it."""
    import click

    from fruitcli.cli.main import cli

    cmds = howto_commands()
    assert len(cmds) >= 15
    ctx = click.Context(cli)
    for page, argv in cmds:
        cmd = cli.get_command(ctx, argv[0])
        assert cmd is not None, (page, argv)
        if isinstance(cmd, click.Group) and len(argv) > 1 and not argv[1].startswith("-"):
            sub = cmd.get_command(ctx, argv[1])
            cmd = sub if sub is not None else cmd
        names = {o for p in cmd.params for o in (*p.opts, *p.secondary_opts)}
        for token in argv[1:]:
            if token.startswith("--"):
                assert token.split("=")[0] in names, (page, token)
