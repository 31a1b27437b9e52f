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
    assert s.material.young_modulus_kpa == 100.0
    assert s.grid.spacing_x_mm == 16.0 and s.grid.spacing_y_mm == 12.0
    assert s.detection.threshold_counts == 20.0
    assert s.chambers[0].ellipsoid.radii_mm == [10.0, 10.0, 10.0]
    assert n_states(s) == 3 and has_deformation(s)
    assert s.has("gravity") and not s.has("bench")


@pytest.mark.parametrize(
    "text,expected",
    [
        (
            "[material]\nyoung_modulus_kp = 3",
            "unknown key 'young_modulus_kp' (did you mean 'young_modulus_kpa'?)",
        ),
        ("[materials]\nx = 1", "unknown section [materials] (did you mean 'material'?)"),
        ("[material]\nyoung_modulus_kpa = 'soft'", "young_modulus_kpa: expected a finite number"),
        ("[material]\nyoung_modulus_kpa = -5", "young_modulus_kpa: expected > 0"),
        ("[material]\npoisson_ratio = 0.5", "poisson_ratio: expected -1 < nu < 0.5"),
        ("[[fixed]]\nbox_mm = [0, 0, 0, 1, 1]", "box_mm: expected a list of 6 numbers"),
        ("[[fixed]]\nbox_mm = [2, 0, 0, 1, 1, 1]", "with min <= max"),
        (
            "[actuation]\npressure_kpa = { c1 = [1.0] }",
            "no such chamber (the scene has no chambers)",
        ),
        ("[geometry]\nsolid = 'a.stl'\npad_size_mm = [1, 1, 1]", "give one of artist, solid"),
        (
            "[detection]\nmethod = 'fancy'",
            "expected one of n9, n9_floor, peaks, fit2, model, got 'fancy'",
        ),
        (
            "[[jig]]\nregion_box_mm = [0, 0, 0, 1, 1, 1]\nstiffness_n_per_mm = 0",
            "stiffness_n_per_mm: expected > 0",
        ),
        ("[[evaluate]]\nlabel = 'x'\ntruth = 't.csv'", "missing key 'measured'"),
        ("x = [", "not valid TOML"),
        ("[solver]\ndisplacement_tolerance_mm = -1", "displacement_tolerance_mm: expected >= 0"),
        ("[solver]\ntolerance = 0", "[solver].tolerance: expected 0 < tolerance < 1"),
        ("[solver]\ntolerance = 1.5", "[solver].tolerance: expected 0 < tolerance < 1"),
        ("[solver]\nmax_seconds = 0", "[solver].max_seconds: expected a time budget > 0 s"),
        ("[solver]\nmax_iterations = 0", "[solver].max_iterations: expected >= 1"),
        ("[solver]\nmax_subdivisions = -1", "[solver].max_subdivisions: expected >= 0"),
    ],
)
def test_bad_scenes_name_the_field(text, expected):
    with pytest.raises(SceneError) as err:
        scene(text)
    assert expected in str(err.value)
    assert "\n" not in str(err.value)


def test_states_must_agree_across_chambers():
    text = MINIMAL.replace(
        "pressure_kpa = { c1 = [0.0, 2.5, 5.0] }",
        "pressure_kpa = { c1 = [0.0, 2.5, 5.0], c2 = [1.0] }",
    )
    text = text.replace(
        "[mesh]",
        '[[geometry.chamber]]\nname = "c2"\n'
        "ellipsoid = { center_mm = [0, 0, 0], radii_mm = [1, 1, 1] }\n[mesh]",
    )
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
    s = parse_scene(
        "[[evaluate]]\nlabel='a'\ntruth='data/t.csv'\nmeasured='data/t.csv'",
        tmp_path / "pipelines" / "s.toml",
    )
    assert s.evaluate[0].truth == tmp_path / "data" / "t.csv"


def test_every_bundled_scene_validates():
    from fruitcli.scene import load_scene
    from tests.conftest import ROOT

    for path in sorted((ROOT / "pipelines").glob("*.toml")):
        load_scene(path, must_exist=False)


def test_readme_scene_example_is_valid():
    import re

    from tests.conftest import ROOT

    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```toml\n(.*?)```", text, re.S)
    assert blocks
    for block in blocks:
        parse_scene(block, ROOT / "pipelines" / "example.toml", must_exist=False)


@pytest.mark.parametrize(
    "text, match",
    [
        ("[grid]\ncount = [4]", r"\[grid\].count: expected two positive integers"),
        ("[grid]\ncount = [4, 0]", r"\[grid\].count: expected two positive integers"),
        ("[grid]\nspacing_x_mm = 0.0", r"\[grid\].spacing_x_mm: expected > 0, got 0.0"),
        ("[bench]\nindenters = []", r"\[bench\].indenters: expected a non-empty list"),
        ("[bench]\nindenters = ['huge']", r"\[bench\].indenters: .* got \['huge'\]"),
        ("[bench]\nstep_mm = 0.0", r"\[bench\].step_mm: expected > 0"),
        ("[bench]\nreference_length_mm = -1.0", r"\[bench\].reference_length_mm: expected > 0"),
        ("[actuation]\nperiod_s = -6.0", r"\[actuation\].period_s: expected > 0"),
        ("[scene]\nname = '../../evil'", r"\[scene\].name: expected a plain folder name"),
    ],
)
def test_values_checked_when_the_scene_is_read(tmp_path, text, match):
    """Each bad value is one error naming the file and the field, before any stage."""
    (tmp_path / "s.toml").write_text(text + "\n")
    with pytest.raises(SceneError, match="^s.toml: " + match):
        load_scene(tmp_path / "s.toml")


# ----------------------------------------------------------------------------- typed sections
def test_typed_sections_agree_with_the_schema():
    """One frozen record type per table section and per array item, with the schema's
    keys in its order and its defaults; a scene declaring nothing holds exactly them."""
    from dataclasses import FrozenInstanceError, fields

    from fruitcli.scene import (
        ARRAY_SCHEMA,
        ARRAY_SECTIONS,
        ITEM_TYPES,
        SCHEMA,
        SECTION_TYPES,
        SUBTABLE_TYPES,
        SUBTABLES,
        default_scene,
    )

    assert set(SECTION_TYPES) == set(SCHEMA) - ARRAY_SECTIONS
    assert set(ITEM_TYPES) == set(ARRAY_SCHEMA) and set(SUBTABLE_TYPES) == set(SUBTABLES)
    pairs = (
        [(SECTION_TYPES[n], SCHEMA[n]) for n in SECTION_TYPES]
        + [(ITEM_TYPES[n], ARRAY_SCHEMA[n]) for n in ITEM_TYPES]
        + [(SUBTABLE_TYPES[n], SUBTABLES[n]) for n in SUBTABLE_TYPES]
    )
    for record, spec in pairs:
        assert [f.name for f in fields(record)] == list(spec)
    defaults = default_scene()
    for name in SECTION_TYPES:
        section = getattr(defaults, name)
        assert isinstance(section, SECTION_TYPES[name])
        assert defaults.values(name) == {k: spec.default for k, spec in SCHEMA[name].items()}
    for name in ARRAY_SECTIONS:
        assert getattr(defaults, name) == ()
    assert defaults.chambers == () and not defaults.declared
    with pytest.raises(FrozenInstanceError):
        defaults.fem.element = "p1"


def test_arrays_are_tuples_of_typed_records():
    s = scene(MINIMAL)
    (chamber,) = s.chambers
    assert type(chamber).__name__ == "ChamberTable" and chamber.name == "c1"
    assert chamber.ellipsoid.center_mm == [0.0, 0.0, 0.0] and chamber.surface is None
    (fixed,) = s.fixed
    assert fixed.box_mm == [-1.0, -1.0, -1.0, 1.0, 1.0, 1.0] and fixed.displacement_mm is None
    assert s.jig == () and s.evaluate == ()
    assert s.values("fixed") == [
        {"box_mm": [-1.0, -1.0, -1.0, 1.0, 1.0, 1.0], "displacement_mm": None}
    ]
    assert s.values("geometry")["chamber"] == [
        {
            "name": "c1",
            "ellipsoid": {"center_mm": [0.0, 0.0, 0.0], "radii_mm": [10.0, 10.0, 10.0]},
            "surface": None,
        }
    ]


def test_an_unknown_section_or_key_fails_loudly():
    s = scene(MINIMAL)
    with pytest.raises(
        AttributeError,
        match=r"FemSection has no key 'elemnt' \(did you mean "
        r"'element'\?\)",
    ):
        s.fem.elemnt  # noqa: B018
    with pytest.raises(
        AttributeError,
        match=r"no section \[materal\] \(did you mean "
        r"'material'\?\)",
    ):
        s.materal  # noqa: B018
    with pytest.raises(AttributeError, match="no key 'radius'"):
        s.chambers[0].radius  # noqa: B018
    with pytest.raises(TypeError):
        s["fem"]
    with pytest.raises(SceneError, match=r"unknown section \[femm\]"):
        s.values("femm")


def test_with_values_checks_and_leaves_the_scene_as_it_was():
    s = scene(MINIMAL)
    t = s.with_values({"fem.element": "p1", "material.model": "corotational", "mesh.size_mm": 2.0})
    assert (t.fem.element, t.material.model, t.mesh.size_mm) == ("p1", "corotational", 2.0)
    assert (s.fem.element, s.material.model, s.mesh.size_mm) == ("p2", "neo-hookean", 3.0)
    assert t.chambers == s.chambers and t.declared == s.declared
    with pytest.raises(
        SceneError,
        match=r"^scene.toml: \[mesh\].size_mm: expected > 0, got "
        r"-1.0$",
    ):
        s.with_values({"mesh.size_mm": -1.0})
    with pytest.raises(
        SceneError,
        match=r"\[fem\].element: expected one of p2, p2-pure, p1, "
        r"got 'p3'",
    ):
        s.with_values({"fem.element": "p3"})
    with pytest.raises(SceneError, match=r"corotational.*linear tets"):  # across keys
        s.with_values({"material.model": "corotational"})
    with pytest.raises(
        SceneError,
        match=r"\[mesh\]: unknown key 'size' \(did you mean "
        r"'size_mm'\?\)",
    ):
        s.with_values({"mesh.size": 1.0})
    skin = s.skin.__class__(contact_counts=80.0)
    assert s.with_values({"skin": skin}).skin.contact_counts == 80.0
    with pytest.raises(SceneError, match=r"\[skin\]: expected a SkinSection"):
        s.with_values({"skin": {"contact_counts": 80.0}})


def _toml(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + " }"
    return repr(value)


BAD_FOR_CONDITION = {  # a value each key's own `valid` condition refuses
    ("scene", "name"): "a/b",
    ("grid", "count"): [4],
    ("reduced", "pressure_range_kpa"): [5.0, 1.0],
    ("printer", "bed_mm"): [0.0, 0.0, 0.0, 0.0, 220.0, 250.0],
    ("jig", "axis"): [0.0, 0.0, 0.0],
    ("skin", "gaps_mm"): [0.5, 1.0],
}
REQUIRED = {"box": [0, 0, 0, 1, 1, 1], "str": "x", "path": "t.csv"}


def _bad_values(where: tuple, spec):
    """Values the key's declared choices, range or condition refuse, each with the number
    that breaks the range (None: not a range's)."""
    if spec.choices is not None:
        yield "not-a-choice", None
    for bound, exclusive, step in (
        (spec.min, spec.min_exclusive, -1),
        (spec.max, spec.max_exclusive, 1),
    ):
        if bound is None:
            continue
        v = bound if exclusive else bound + step
        v = int(v) if spec.kind == "int" else float(v)
        if spec.kind == "table":
            yield {"small": v}, v
        elif spec.kind == "box":
            lo, hi = (v, 0.0) if step < 0 else (0.0, v)
            yield [lo, lo, lo, hi, hi, hi], v
        elif spec.kind == "vec2":
            yield [1.0, v], v
        elif spec.kind.startswith("vec"):
            yield [1.0, 1.0, v], v
        else:
            yield v, v
    if spec.valid is not None:
        yield BAD_FOR_CONDITION[where], None


def _declared_keys():
    from fruitcli.scene import ARRAY_SCHEMA, SCHEMA, SUBTABLES

    out = []
    for section, keys in SCHEMA.items():
        out += [(section, key, spec) for key, spec in keys.items()]
    for array, keys in ARRAY_SCHEMA.items():
        out += [(array, key, spec) for key, spec in keys.items()]
    out += [("ellipsoid", key, spec) for key, spec in SUBTABLES["ellipsoid"].items()]
    return [
        (s, k, spec, bad, number) for s, k, spec in out for bad, number in _bad_values((s, k), spec)
    ]


def _scene_with(section: str, key: str, value) -> str:
    from fruitcli.scene import ARRAY_SCHEMA

    if section == "ellipsoid":
        sub = {"center_mm": [0, 0, 0], "radii_mm": [1, 1, 1], key: value}
        return f"[[geometry.chamber]]\nname = 'c'\nellipsoid = {_toml(sub)}\n"
    if section not in ARRAY_SCHEMA:
        return f"[{section}]\n{key} = {_toml(value)}\n"
    item = {k: REQUIRED[s.kind] for k, s in ARRAY_SCHEMA[section].items() if s.required}
    item[key] = value
    return f"[[{section}]]\n" + "".join(f"{k} = {_toml(v)}\n" for k, v in item.items())


CHECKED_KEYS = {
    "actuation": "period_s pressure_kpa volume_growth_mm3",
    "bench": "baseline_frames reference_length_mm register seed state step_mm",
    "board": "cols format offset_i offset_j rows",
    "detection": "baseline_frames debounce_frames drift_rate hover_hysteresis_counts "
    "hover_threshold_counts hysteresis_counts method model_frames noise_floor_counts project "
    "threshold_counts track_gate_mm",
    "ellipsoid": "center_mm radii_mm",
    "evaluate": "reference_length_mm register",
    "fem": "element",
    "fixed": "box_mm displacement_mm",
    "frames": "model",
    "geometry": "fit_mm pad_size_mm unit",
    "gravity": "vector_m_s2",
    "grid": "count origin_mm spacing_x_mm spacing_y_mm",
    "jig": "axis pivot_mm region_box_mm rotate_deg stiffness_n_per_mm translate_mm",
    "material": "bulk_modulus_kpa c10_kpa c20_kpa c30_kpa density_kg_m3 model poisson_ratio "
    "young_modulus_kpa",
    "mesh": "min_quality min_size_mm size_mm time_limit_s",
    "mold": "clearance_mm key_radius_mm pin_diameter_mm pour_diameter_mm vent_diameter_mm vents "
    "wall_mm",
    "printer": "baud bed_mm feed_mm_min max_press_mm model_origin_mm rotate_z_deg safe_height_mm "
    "step_mm timeout_s",
    "reduced": "margin max_degree points_per_axis pressure_range_kpa seed validation",
    "scene": "name",
    "sensitivity": "animation_frames noise_frames",
    "skin": "contact_counts counts_per_ff footprint_sigma_mm gain_spread gap_decay_mm gaps_mm "
    "height_as_distance height_as_gap widening_per_mm "
    "insulation_mm model noise_std_counts permittivity yarn_radius_mm",
    "solver": "displacement_tolerance_mm first_steps jig_steps linear_solver max_iterations "
    "max_seconds max_subdivisions tolerance",
    "tracks": "cover_mm faces split_z_mm track_radius_mm yarn_max_stretch zigzag_pitch_mm",
}


def test_the_schema_declares_the_checks_of_these_keys():
    declared = {(s, k) for s, k, *_ in _declared_keys()}
    assert declared == {(s, k) for s, keys in CHECKED_KEYS.items() for k in keys.split()}


@pytest.mark.parametrize(
    "section, key, spec, bad, number",
    _declared_keys(),
    ids=lambda v: v if isinstance(v, str) else None,
)
def test_every_declared_range_and_choice_refuses_a_bad_value(section, key, spec, bad, number):
    """One line naming the file and the key, what was expected (the side of the range the
    value broke) and what was given."""
    with pytest.raises(SceneError) as err:
        parse_scene(_scene_with(section, key, bad), Path("/tmp/s.toml"), must_exist=False)
    msg = str(err.value)
    assert msg.startswith("s.toml: ") and "\n" not in msg
    expected = spec.expectation(number)
    assert (
        f".{key}: expected {expected}, got " in msg
        or f".{key}.small: expected {expected}, got {number!r}" in msg
    )


NUMERIC_KINDS = {"num", "int", "vec2", "vec3", "box", "range"}
NUMERIC_TABLES = {"footprint_sigma_mm", "pressure_kpa", "volume_growth_mm3"}


def _all_keys():
    from fruitcli.scene import ARRAY_SCHEMA, SCHEMA, SUBTABLES

    for group in (SCHEMA, ARRAY_SCHEMA, SUBTABLES):
        for section, keys in group.items():
            yield from ((section, key, spec) for key, spec in keys.items())


def test_no_numeric_key_is_unbounded_without_a_reason():
    """Every number, vector and table of numbers has both ends of its range in the schema,
    or says in `unbounded` where the missing end is checked."""
    open_ended = [
        f"{section}.{key}"
        for section, key, spec in _all_keys()
        if (spec.kind in NUMERIC_KINDS or key in NUMERIC_TABLES)
        and (spec.min is None or spec.max is None)
        and not spec.unbounded
    ]
    assert open_ended == []


def test_every_list_and_table_key_has_a_length_bound():
    unbounded = [
        f"{section}.{key}"
        for section, key, spec in _all_keys()
        if spec.kind in ("list", "table") and key != "ellipsoid" and spec.max_items is None
    ]
    assert unbounded == []


@pytest.mark.parametrize(
    "text, line",
    [
        (
            "[bench]\nindenters = [" + ", ".join(['"small"'] * 100_000) + "]",
            "s.toml: [bench].indenters: expected at most 64 entries, got 100,000",
        ),
        (
            "[[fixed]]\nbox_mm = [0, 0, 0, 1, 1, 1]\n" * 1001,
            "s.toml: [[fixed]]: expected at most 1,000 tables, got 1,001",
        ),
        (
            "[[geometry.chamber]]\nname = 'c'\nsurface = 'c.stl'\n"
            "[actuation]\npressure_kpa = { c = [" + ", ".join(["1.0"] * 10_001) + "] }",
            "s.toml: [actuation].pressure_kpa.c: expected at most 10,000 states, got 10,001",
        ),
        ("[solver]\nmax_subdivisions = -1", "s.toml: [solver].max_subdivisions: expected >= 0"),
        ("[mesh]\ntime_limit_s = -1", "s.toml: [mesh].time_limit_s: expected a time limit > 0 s"),
        ("[board]\nrows = 0", "s.toml: [board].rows: expected >= 1, got 0"),
        (
            "[skin]\ncontact_counts = 1e300",
            "s.toml: [skin].contact_counts: expected 0 < value <= 65535, got 1e+300",
        ),
        (
            "[solver]\nmax_seconds = 1e300",
            "s.toml: [solver].max_seconds: expected a time budget > 0 s and <= 1e+06, got 1e+300",
        ),
        (
            "[geometry]\npad_size_mm = [1e9, 1e9, 3.0]",
            "s.toml: [geometry].pad_size_mm: expected [x, y, thickness] each > 0 and <= 5000 mm",
        ),
        (
            "[actuation]\npressure_kpa = { c = [1.0, 1e7] }",
            "s.toml: [actuation].pressure_kpa.c: expected pressures -100000 <= p <= 100000 kPa, "
            "one per state, got 10000000.0",
        ),
    ],
    ids=lambda v: v[:40],
)
def test_sizes_and_ranges_are_refused_in_one_line(text, line):
    with pytest.raises(SceneError) as err:
        parse_scene(text, Path("/tmp/s.toml"), must_exist=False)
    assert str(err.value).startswith(line) and "\n" not in str(err.value)


def test_a_long_value_is_echoed_cut():
    """A value echoed in an error is cut to a readable length."""
    from fruitcli.errors import ECHO_CHARS

    with pytest.raises(SceneError) as err:
        parse_scene("[scene]\nname = [" + "1, " * 1_000_000 + "]", Path("/tmp/s.toml"), False)
    msg = str(err.value)
    assert msg.startswith("s.toml: [scene].name: expected a string, got [1, 1, ")
    assert msg.endswith("…") and len(msg) < 60 + ECHO_CHARS
