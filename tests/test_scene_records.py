"""The scene's written records (`fruitcli.scene.records`) match the schema key for key
(name, order, type, default), and a type checker sees them: a misspelt key is a mypy
error, not `Any`."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import pytest

from fruitcli.scene import ARRAY_SCHEMA, ARRAY_SECTIONS, SCHEMA, SUBTABLES, Key, default_scene
from fruitcli.scene.key import KIND_TYPES
from fruitcli.scene.records import ITEM_TYPES, SECTION_TYPES, SUBTABLE_TYPES, Record, Sections

ROOT = Path(__file__).resolve().parents[1]


def expected_type(name: str, spec: Key, nested: dict[str, str]) -> str:
    """The annotation a key's field should have: its kind's type, `| None` when it may be
    unset (default None and not required); a nested record's as given."""
    if name in nested:
        return nested[name]
    optional = spec.default is None and not spec.required
    return KIND_TYPES[spec.kind] + (" | None" if optional else "")


def mismatches(record: type, spec: dict[str, Key], nested: dict[str, str]) -> list[str]:
    """One line per way `record` differs from the schema's keys `spec`."""
    out = []
    if not (dataclasses.is_dataclass(record) and issubclass(record, Record)):
        return [f"{record.__name__}: not a dataclass Record"]
    if not record.__dataclass_params__.frozen:  # type: ignore[attr-defined]
        out.append(f"{record.__name__}: not frozen")
    fields = {f.name: f for f in dataclasses.fields(record)}
    if list(fields) != list(spec):
        out.append(f"{record.__name__}: fields {list(fields)}, schema keys {list(spec)}")
    for name in fields.keys() & spec.keys():
        f, key = fields[name], spec[name]
        want = expected_type(name, key, nested)
        if f.type != want:
            out.append(f"{record.__name__}.{name}: type {f.type}, expected {want}")
        if f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            default = f.default
        if key.required:
            if default is not dataclasses.MISSING:
                out.append(f"{record.__name__}.{name}: required, but defaults to {default!r}")
        elif name in nested:
            want_default = () if key.default == [] else key.default
            if default != want_default:
                out.append(f"{record.__name__}.{name}: default {default!r}")
        elif default != key.default or type(default) is not type(key.default):
            out.append(f"{record.__name__}.{name}: default {default!r}, expected {key.default!r}")
    return out


def test_the_written_records_match_the_schema():
    """Every section, array item and sub-table: a frozen Record with the schema's keys in
    its order, each typed by its kind and defaulting as the schema says."""
    assert set(SECTION_TYPES) == set(SCHEMA) - ARRAY_SECTIONS
    assert set(ITEM_TYPES) == set(ARRAY_SCHEMA) and set(SUBTABLE_TYPES) == set(SUBTABLES)
    found = []
    for name, record in SUBTABLE_TYPES.items():
        found += mismatches(record, SUBTABLES[name], {})
    for name, record in ITEM_TYPES.items():
        nested = {k: f"{SUBTABLE_TYPES[k].__name__} | None" for k in SUBTABLES}
        found += mismatches(record, ARRAY_SCHEMA[name], nested)
    for name, record in SECTION_TYPES.items():
        nested = {"chamber": "tuple[ChamberTable, ...]"} if name == "geometry" else {}
        found += mismatches(record, SCHEMA[name], nested)
    assert found == []


def test_the_sections_are_typed_as_the_schema_lists_them():
    """`Sections` (which `Scene` extends) names every section in the schema's order: a
    table as its record, an array of tables as a tuple of its item's record."""
    want = {
        name: f"tuple[{ITEM_TYPES[name].__name__}, ...]"
        if name in ARRAY_SECTIONS
        else SECTION_TYPES[name].__name__
        for name in SCHEMA
    }
    assert Sections.__annotations__ == {**want, "declared": "frozenset[str]"}


def test_every_section_names_the_closest_key_at_run_time():
    """At run time a misspelt key of any section is an AttributeError naming the record
    and the closest key (a type checker sees it before: the test below)."""
    scene = default_scene()
    for name, record in SECTION_TYPES.items():
        key = next(iter(SCHEMA[name]))
        with pytest.raises(AttributeError) as err:
            getattr(getattr(scene, name), key + "z")
        assert str(err.value) == (f"{record.__name__} has no key '{key}z' (did you mean '{key}'?)")


def test_a_record_unlike_its_keys_is_reported():
    """The comparison above fails on a record that drifted from its keys: a missing key,
    a wrong type, a wrong default, a mutable record."""

    @dataclasses.dataclass(frozen=True)
    class Toy(Record):
        size_mm: float = 2.0
        name: str = "a"

    @dataclasses.dataclass
    class Loose(Record):
        size_mm: float = 3.0

    spec = {"size_mm": Key("num", 3.0), "name": Key("str", None), "count": Key("int", 1)}
    found = mismatches(Toy, spec, {})
    assert "Toy.size_mm: default 2.0, expected 3.0" in found
    assert "Toy.name: type str, expected str | None" in found
    assert "Toy.name: default 'a', expected None" in found
    assert any(line.startswith("Toy: fields") for line in found)
    assert mismatches(Loose, {"size_mm": Key("num", 3.0)}, {}) == ["Loose: not frozen"]


def test_a_misspelt_key_is_a_type_error(tmp_path):
    """mypy (with the project's settings) reports a misspelt key, a misspelt section and a
    key's value used as the wrong type, and accepts a str method on [fem].element."""
    pytest.importorskip("mypy")
    (tmp_path / "use.py").write_text(
        "from fruitcli.scene import default_scene\n"
        "scene = default_scene()\n"
        "ok: str = scene.fem.element.upper()\n"
        "wrong: int = scene.fem.element\n"
        "scene.fem.elemnt\n"
        "scene.materal\n"
    )
    res = subprocess.run(
        [sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml")]
        + ["--cache-dir", str(tmp_path / "cache"), "--no-error-summary", "use.py"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env={**os.environ, "MYPYPATH": str(ROOT)},  # this checkout's fruitcli
        timeout=600,
    )
    assert [line.split(": error: ")[1] for line in res.stdout.splitlines()] == [
        'Incompatible types in assignment (expression has type "str", variable has type '
        '"int")  [assignment]',
        '"FemSection" has no attribute "elemnt"; maybe "element"?  [attr-defined]',
        '"Scene" has no attribute "materal"  [attr-defined]',
    ]
