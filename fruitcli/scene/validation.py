"""One section's or array item's keys checked against the schema: unknown and missing
keys, each value's type (`kinds`), then its choices, range and condition
(`check_value`); defaults filled in. The checks across keys are `cross_checks`."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

from fruitcli.errors import SceneError, echo
from fruitcli.scene.key import Key, closest, number
from fruitcli.scene.kinds import check_kind
from fruitcli.scene.limits import MAX_ITEMS
from fruitcli.scene.records import ITEM_TYPES, SUBTABLE_TYPES, Record
from fruitcli.scene.schema import ARRAY_SCHEMA, ITEM_LABELS, SUBTABLES


def copy_plain(value: Any) -> Any:
    """A deep copy of nested lists and dicts (a default handed to a record)."""
    if isinstance(value, list):
        return [copy_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: copy_plain(v) for k, v in value.items()}
    return value


def check_value(where: str, key: str, spec: Key, value: Any) -> None:
    """The declared choices, range and condition of a typed value (None: unset, fine)."""
    if value is None:
        return

    def fail(name: str = key, got: Any = value, hint: str = "", number: Any = None) -> NoReturn:
        expected = spec.expectation(got if number is None else number)
        raise SceneError(f"{where}.{name}: expected {expected}, got {echo(got)}{hint}")

    if spec.choices is not None and value not in spec.choices:
        fail(hint=closest(str(value), spec.choices))
    if spec.min is not None or spec.max is not None:
        _check_range(key, spec, value, fail)
    if spec.valid is not None and not spec.valid(value):
        fail()


def _check_range(key: str, spec: Key, value: Any, fail: Callable[..., NoReturn]) -> None:
    """A number, each number of a list, or each entry of a table within the key's range."""
    if isinstance(value, dict):
        for entry, v in value.items():
            # a table's entry: a number, or a list of numbers (one per state)
            if isinstance(v, list) and spec.kind == "table" and spec.valid is None:
                bad = [x for x in v if number(x) and not spec.in_range(x)]
                if bad:
                    fail(f"{key}.{entry}", bad[0])
            elif not number(v) or not spec.in_range(v):
                fail(f"{key}.{entry}", v)
    elif isinstance(value, list):
        # numbers out of range (anything else is the `valid` condition's to refuse)
        out = [v for v in value if number(v) and not spec.in_range(v)]
        if out:
            fail(number=out[0])
    elif not spec.in_range(value):
        fail()


def check_values(where: str, values: dict, spec: dict[str, Key]) -> None:
    """`check_value` on every key of a validated table (and of the tables inside it)."""
    for key, kspec in spec.items():
        if key in SUBTABLES and isinstance(values[key], dict):
            check_values(f"{where}.{key}", values[key], SUBTABLES[key])
        else:
            check_value(where, key, kspec, values[key])


def validate_table(
    where: str, table: Any, spec: dict[str, Key], scene_path: Path, must_exist: bool
) -> dict[str, Any]:
    """A TOML table's keys type-checked, with every key the table leaves out at its
    default; an unknown key or a missing required one raises `SceneError`."""
    if not isinstance(table, dict):
        raise SceneError(f"{where}: expected a table, got {type(table).__name__}")
    out = {}
    for key, value in table.items():
        if key not in spec:
            raise SceneError(f"{where}: unknown key '{key}'{closest(key, spec)}")
        if key in SUBTABLES:
            sub = check_kind(where, key, spec[key], value, scene_path, must_exist)
            out[key] = validate_table(f"{where}.{key}", sub, SUBTABLES[key], scene_path, must_exist)
            for sk, sspec in SUBTABLES[key].items():
                if sspec.required and sk not in out[key]:
                    raise SceneError(f"{where}.{key}: missing key '{sk}'")
            continue
        out[key] = check_kind(where, key, spec[key], value, scene_path, must_exist)
    for key, kspec in spec.items():
        if key not in out:
            if kspec.required:
                raise SceneError(f"{where}: missing key '{key}' ({kspec.doc})")
            out[key] = copy_plain(kspec.default)
    return out


def items(
    where0: str, array: str, tables: list, scene_path: Path, must_exist: bool
) -> tuple[Record, ...]:
    """Validate an array of tables into a tuple of typed records."""
    spec, label = ARRAY_SCHEMA[array], ITEM_LABELS.get(array)
    if len(tables) > MAX_ITEMS:
        raise SceneError(
            f"{where0}: [[{array}]]: expected at most {MAX_ITEMS:,} tables, got {len(tables):,}"
        )
    records = []
    for n, item in enumerate(tables):
        out = validate_table(f"{where0}: [[{array}]] #{n + 1}", item, spec, scene_path, must_exist)
        named = f"'{out[label]}'" if label else f"#{n + 1}"
        check_values(f"{where0}: [[{array}]] {named}", out, spec)
        for key in SUBTABLES:
            if key in out and out[key] is not None:
                out[key] = SUBTABLE_TYPES[key](**out[key])
        records.append(ITEM_TYPES[array](**out))
    return tuple(records)
