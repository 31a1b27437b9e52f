"""Scene validation: defaults, unknown keys with suggestions, types, files, cross checks."""

from __future__ import annotations

from pathlib import Path

import pytest

from fruitcli.errors import SceneError
from fruitcli.scene import has_deformation, load_scene, n_states, parse_scene

MINIMAL = """
[geometry]
solid = "body.stl"
[[geometry.chamber]]
name = "c1"
ellipsoid = { center_mm = [0, 0, 0], radii_mm = [10, 10, 10] }
[mesh]
size_mm = 3.0
[material]
young_modulus_kpa = 100.0
poisson_ratio = 0.45
density_kg_m3 = 1070.0
[gravity]
vector_m_s2 = [0.0, 0.0, -9.81]
[[fixed]]
box_mm = [-1, -1, -1, 1, 1, 1]
[actuation]
pressure_kpa = { c1 = [0.0, 2.5, 5.0] }
"""


def scene(text, must_exist=False):
    return parse_scene(text, Path("/tmp/scene.toml"), must_exist=must_exist)


def test_minimal_keys_and_defaults():
    s = scene(MINIMAL)
    assert s["material"]["young_modulus_kpa"] == 100.0
    assert s["grid"]["spacing_x_mm"] == 16.0 and s["grid"]["spacing_y_mm"] == 12.0
    assert s["detection"]["threshold_counts"] == 20.0
    assert s.chambers[0]["ellipsoid"]["radii_mm"] == [10.0, 10.0, 10.0]
    assert n_states(s) == 3 and has_deformation(s)
    assert s.has("gravity") and not s.has("bench")


@pytest.mark.parametrize("text,expected", [
    ("[material]\nyoung_modulus_kp = 3", "unknown key 'young_modulus_kp' (did you mean "
     "'young_modulus_kpa'?)"),
    ("[materials]\nx = 1", "unknown section [materials] (did you mean 'material'?)"),
    ("[material]\nyoung_modulus_kpa = 'soft'", "young_modulus_kpa: expected a finite number"),
    ("[material]\nyoung_modulus_kpa = -5", "young_modulus_kpa: expected > 0"),
    ("[material]\npoisson_ratio = 0.5", "poisson_ratio: expected -1 < nu < 0.5"),
    ("[[fixed]]\nbox_mm = [0, 0, 0, 1, 1]", "box_mm: expected a list of 6 numbers"),
    ("[[fixed]]\nbox_mm = [2, 0, 0, 1, 1, 1]", "with min <= max"),
    ("[actuation]\npressure_kpa = { c1 = [1.0] }", "no such chamber (the scene has no chambers)"),
    ("[geometry]\nsolid = 'a.stl'\npad_size_mm = [1, 1, 1]", "give one of artist, solid"),
    ("[detection]\nmethod = 'fancy'", "expected n9, n9_floor, peaks or fit2"),
    ("[[jig]]\nregion_box_mm = [0, 0, 0, 1, 1, 1]\nstiffness_n_per_mm = 0",
     "stiffness_n_per_mm: expected > 0"),
    ("[[evaluate]]\nlabel = 'x'\ntruth = 't.csv'", "missing key 'measured'"),
    ("x = [", "not valid TOML"),
    ("[solver]\ndisplacement_tolerance_mm = -1", "displacement_tolerance_mm >= 0"),
])
def test_bad_scenes_name_the_field(text, expected):
    with pytest.raises(SceneError) as err:
        scene(text)
    assert expected in str(err.value)
    assert "\n" not in str(err.value)


def test_states_must_agree_across_chambers():
    text = MINIMAL.replace('pressure_kpa = { c1 = [0.0, 2.5, 5.0] }',
                           'pressure_kpa = { c1 = [0.0, 2.5, 5.0], c2 = [1.0] }')
    text = text.replace('[mesh]', '[[geometry.chamber]]\nname = "c2"\n'
                        'ellipsoid = { center_mm = [0, 0, 0], radii_mm = [1, 1, 1] }\n[mesh]')
    with pytest.raises(SceneError, match="same number of states"):
        scene(text)


def test_missing_file_names_the_field(tmp_path):
    with pytest.raises(SceneError, match=r"\[geometry\].solid: file not found: body.stl"):
        parse_scene(MINIMAL, tmp_path / "s.toml", must_exist=True)


def test_chamber_needs_one_shape():
    with pytest.raises(SceneError, match="exactly one of ellipsoid or surface"):
        scene("[[geometry.chamber]]\nname = 'c'\n")


def test_paths_resolve_against_scene_folder_then_project_root(tmp_path):
    (tmp_path / "pyproject.toml").write_text("")
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "t.csv").write_text("")
    (tmp_path / "pipelines").mkdir()
    s = parse_scene("[[evaluate]]\nlabel='a'\ntruth='data/t.csv'\nmeasured='data/t.csv'",
                    tmp_path / "pipelines" / "s.toml")
    assert s["evaluate"][0]["truth"] == tmp_path / "data" / "t.csv"


def test_every_bundled_scene_validates():
    from conftest import ROOT

    from fruitcli.scene import load_scene

    for path in sorted((ROOT / "pipelines").glob("*.toml")):
        load_scene(path, must_exist=False)


def test_readme_scene_example_is_valid():
    import re

    from conftest import ROOT

    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```toml\n(.*?)```", text, re.S)
    assert blocks
    for block in blocks:
        parse_scene(block, ROOT / "pipelines" / "example.toml", must_exist=False)


@pytest.mark.parametrize("text, match", [
    ("[grid]\ncount = [4]", r"\[grid\].count: expected two positive integers"),
    ("[grid]\ncount = [4, 0]", r"\[grid\].count: expected two positive integers"),
    ("[grid]\nspacing_x_mm = 0.0", r"\[grid\]: expected spacing_x_mm and spacing_y_mm > 0"),
    ("[bench]\nindenters = []", r"\[bench\].indenters: expected a non-empty list"),
    ("[bench]\nindenters = ['huge']", r"\[bench\].indenters: .* got \['huge'\]"),
    ("[bench]\nstep_mm = 0.0", r"\[bench\].step_mm: expected > 0"),
    ("[bench]\nreference_length_mm = -1.0", r"\[bench\].reference_length_mm: expected > 0"),
    ("[actuation]\nperiod_s = -6.0", r"\[actuation\].period_s: expected > 0"),
    ("[scene]\nname = '../../evil'", r"\[scene\].name: expected a plain folder name"),
])
def test_values_checked_when_the_scene_is_read(tmp_path, text, match):
    """Each bad value is one error naming the file and the field, before any stage."""
    (tmp_path / "s.toml").write_text(text + "\n")
    with pytest.raises(SceneError, match="^s.toml: " + match):
        load_scene(tmp_path / "s.toml")
