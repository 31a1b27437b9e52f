"""Two bench indenters of one name, or two evaluation rows whose labels name one folder,
are refused by the scene's validation in one line naming the keys."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import SceneError
from fruitcli.scene import parse_scene
from tests.conftest import PAPER

PAD = """
[scene]
configuration = "Rest"
[geometry]
pad_size_mm = [40.0, 40.0, 3.0]
"""


def _row(label):
    truth = PAPER / "paper_rest_truth.csv"
    measured = PAPER / "paper_rest_measured.csv"
    return f'[[evaluate]]\nlabel = "{label}"\ntruth = "{truth}"\nmeasured = "{measured}"\n'


@pytest.mark.parametrize(
    "text,message",
    [
        (
            PAD + '[bench]\nindenters = ["small", "medium", "small"]\n',
            "s.toml: [bench].indenters: 'small' is given twice; expected each indenter once "
            "(it names its folders)",
        ),
        (
            _row("Rest, small") + _row("rest small"),
            "s.toml: [[evaluate]].label 'rest small' and [[evaluate]].label 'Rest, small' both "
            "name the folder evaluate/rest-small; expected row labels that differ in more than "
            "case and punctuation",
        ),
        (
            PAD + '[bench]\nindenters = ["small"]\n' + _row("REST / small"),
            "s.toml: [scene].configuration with [bench].indenters 'Rest, small' and "
            "[[evaluate]].label 'REST / small' both name the folder evaluate/rest-small; "
            "expected row labels that differ in more than case and punctuation",
        ),
    ],
)
def test_rows_that_would_share_a_folder_are_refused(tmp_path, text, message):
    with pytest.raises(SceneError) as err:
        parse_scene(text, tmp_path / "s.toml")
    assert str(err.value) == message
    (tmp_path / "s.toml").write_text(text)
    res = CliRunner().invoke(cli, ["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "o")])
    assert res.exit_code == 1 and res.output.splitlines() == [f"Error: {message}"]
    assert not (tmp_path / "o").exists()


def test_rows_with_folders_of_their_own_are_taken(tmp_path):
    scene = parse_scene(
        PAD + '[bench]\nindenters = ["small", "medium"]\n' + _row("Rest, large"),
        tmp_path / "s.toml",
    )
    assert list(scene.bench.indenters) == ["small", "medium"]
