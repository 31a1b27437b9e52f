"""The tables of choices: the scene schema's choices and defaults, the command line's
choices and the dispatch read each table, so an entry added to a table is accepted
everywhere at once."""

from __future__ import annotations

import click
import pytest

from fruitcli.evaluation.registrations import REGISTRATIONS
from fruitcli.fem.elements.families import ELEMENT_FAMILIES
from fruitcli.fem.elements.lagrange import ELEMENTS
from fruitcli.fem.materials.models import MATERIAL_MODELS
from fruitcli.fem.solver.solvers import LINEAR_SOLVERS
from fruitcli.geometry.mesh.units import UNIT_TO_MM
from fruitcli.scene import ARRAY_SCHEMA, SCHEMA, default_scene, parse_scene
from fruitcli.sensing.detection.methods import METHODS
from fruitcli.sensing.frames.formats import BOARD_COLS, BOARD_FORMATS, BOARD_ROWS
from fruitcli.sensing.skin.models import SKIN_MODELS

SCHEMA_CHOICES = [
    (SCHEMA["geometry"]["unit"], tuple(UNIT_TO_MM)),
    (SCHEMA["fem"]["element"], tuple(ELEMENT_FAMILIES)),
    (SCHEMA["material"]["model"], tuple(MATERIAL_MODELS)),
    (SCHEMA["solver"]["linear_solver"], tuple(LINEAR_SOLVERS)),
    (SCHEMA["board"]["format"], ("auto", *BOARD_FORMATS)),
    (SCHEMA["detection"]["method"], tuple(METHODS)),
    (SCHEMA["bench"]["register"], tuple(REGISTRATIONS)),
    (ARRAY_SCHEMA["evaluate"]["register"], tuple(REGISTRATIONS)),
    (SCHEMA["skin"]["model"], tuple(SKIN_MODELS)),
]


@pytest.mark.parametrize(("key", "table"), SCHEMA_CHOICES)
def test_the_schema_reads_each_table(key, table):
    assert key.choices == table


def test_the_board_defaults_are_the_tables():
    board = default_scene().board
    assert (board.rows, board.cols) == (BOARD_ROWS, BOARD_COLS) == (21, 12)


def test_the_element_rules_carry_the_table():
    assert list(ELEMENTS) == list(ELEMENT_FAMILIES)
    for name, fam in ELEMENTS.items():
        assert fam.nodes_per_tet == ELEMENT_FAMILIES[name].nodes_per_tet
        pts, w = fam.volume_rule()
        assert w.sum() == pytest.approx(1 / 6)  # the reference tet's volume


def test_the_corotational_material_runs_on_linear_tets_only(tmp_path):
    """The scene's cross-check reads `MaterialModel.runs_on`: corotational on p2 is refused
    with the one-line message, on p1 accepted."""
    corot = MATERIAL_MODELS["corotational"]
    assert corot.corotational and corot.runs_on("p1") and not corot.runs_on("p2")
    assert all(
        m.runs_on(e) for m in MATERIAL_MODELS.values() if not m.corotational for e in ELEMENTS
    )
    text = '[geometry]\npad_size_mm = [40, 30, 5]\n[material]\nmodel = "corotational"\n'
    assert parse_scene(text + '[fem]\nelement = "p1"\n', tmp_path / "s.toml").fem.element == "p1"
    from fruitcli.errors import SceneError

    with pytest.raises(SceneError, match=r'set \[fem\].element = "p1"'):
        parse_scene(text + '[fem]\nelement = "p2"\n', tmp_path / "s.toml")


@pytest.mark.parametrize(
    ("command", "option", "table"),
    [
        ("locate", "method", tuple(METHODS)),
        ("evaluate", "register", tuple(REGISTRATIONS)),
        ("make-tracks", "unit", tuple(UNIT_TO_MM)),
        ("record", "fmt", tuple(BOARD_FORMATS)),
    ],
)
def test_the_command_line_reads_each_table(command, option, table):
    from fruitcli.cli.main import cli

    params = {p.name: p for p in cli.get_command(click.Context(cli), command).params}
    choices = tuple(c for c in params[option].type.choices if c != "auto")
    assert choices == table


def test_the_board_module_builds_no_scene_at_import():
    """`sensing.frames.board` takes the [board] defaults from its table, not from a scene
    built at import (a fresh interpreter counts the calls of `default_scene`)."""
    import subprocess
    import sys

    code = (
        "import fruitcli.scene as s\n"
        "calls = []\n"
        "real = s.default_scene\n"
        "s.default_scene = lambda: calls.append(1) or real()\n"
        "import fruitcli.sensing.frames.board as b\n"
        "print(len(calls), b.BOARD_ROWS, b.BOARD_COLS)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["0", "21", "12"]


def test_every_function_a_table_names_loads():
    """Each detection method's `find` and each material model's `constants` names a
    function that imports, with the calling convention's parameters."""
    import inspect

    named = [(m.name, m.finder()) for m in METHODS.values() if m.find]
    assert [n for n, _ in named] == ["peaks", "fit2"]
    for _, f in named:
        assert list(inspect.signature(f).parameters) == [
            "flat", "grid", "threshold", "floor", "max_touches", "footprint"
        ]  # fmt: skip
    for m in MATERIAL_MODELS.values():
        assert list(inspect.signature(m.builder()).parameters) == ["keys", "where"], m.name
