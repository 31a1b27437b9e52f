"""Tutorial 1 as written: its commands run in order in one folder, and the files and
claims the page names hold (a stage "taken over" or "reused" is one the planner
reports as reuse)."""

from __future__ import annotations

import re
import shlex

import pytest

from tests.conftest import ROOT

PAGE = ROOT / "docs" / "tutorials" / "fruit-to-table-1.md"


def commands(text: str) -> list[str]:
    """The lines of the page's ```shell blocks, in order."""
    blocks = re.findall(r"```shell\n(.*?)```", text, re.S)
    return [line for block in blocks for line in block.splitlines() if line.strip()]


def named_paths(text: str) -> list[str]:
    """Paths the page's prose names in backticks (no placeholders such as <indenter>)."""
    prose = re.sub(r"```.*?```", "", text, flags=re.S)
    return [
        p
        for p in re.findall(r"`([^`\s]+)`", prose)
        if "/" in p and "<" not in p and p.split("/")[0] in ("out", "table", "rest", "deformed")
    ]


def _plan(text: str) -> dict[str, str]:
    """stage -> action of a printed plan (the lines `name  action  reason`)."""
    return dict(re.findall(r"^([a-z-]+) +(run|reuse|not needed) ", text, re.M))


@pytest.mark.slow
def test_tutorial_1_as_written(fruit, tmp_path, monkeypatch):
    text = PAGE.read_text()
    monkeypatch.chdir(tmp_path)
    outputs = {}
    for line in commands(text):
        argv = shlex.split(line)
        if argv[0] == "cat":
            outputs[line] = (tmp_path / argv[1]).read_text()
            continue
        assert argv[0] == "fruit", line
        res = fruit(*argv[1:])
        assert res.exit_code == 0, (line, res.output)
        outputs[line] = res.output
    # "table.md gives the paper's row exactly: 29 samples at rest, 2.56 mm mean error
    # (1.7 % of 152 mm) and 1.28 mm standard deviation"; the deformed row 3.81 mm (2D)
    table = outputs["cat out/paper-table/evaluate/table.md"]
    assert "| Rest, small | 29 | 3D | none | 2.56 mm (1.7 %) | 1.28 mm (0.8 %) |" in table
    assert "| Deformed, small (top view) | 29 | top view (x, y) | none | 3.81 mm " in table
    # "--dry-run prints the plan: make-artist writes the default Fruit ..."; no FEM
    plan = _plan(outputs["fruit run rest/fruit-rest.toml --out out/fruit-rest --dry-run"])
    assert plan["make-artist"] == "run" and plan["tetra"] == "not needed"
    # "Run the last command again: every stage is reused"
    res = fruit("run", "rest/fruit-rest.toml", "--out", "out/fruit-rest")
    again = _plan(res.output)
    assert "run" not in again.values() and again["bench"] == "reuse", res.output
    # "make-artist runs once more ... every other stage that ran above is reused"
    report = (tmp_path / "out" / "report.md").read_text()
    ran = re.findall(r"^([a-z-]+) +run ", report, re.M)
    assert ran == ["make-artist"], report
    for path in named_paths(text):  # every file and folder the page names
        assert (tmp_path / path).exists(), path
    assert not (tmp_path / "out/paper-table/evaluate/deformed-small-top-view/side.png").exists()
    # and the tutorial's own scene still plans nothing to run after the demo
    res = fruit("run", "rest/fruit-rest.toml", "--out", "out/fruit-rest", "--dry-run")
    assert "run" not in _plan(res.output).values(), res.output


def test_tutorial_1_names_its_commands_and_files():
    """The parser above finds what the page holds (a cheap guard for the slow test)."""
    text = PAGE.read_text()
    cmds = commands(text)
    assert cmds[0] == "fruit scenes" and cmds[-1].startswith("fruit demo --out out")
    assert "out/paper-table/evaluate/rest-small/side.png" in named_paths(text)
