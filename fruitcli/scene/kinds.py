"""A scene value's type, checked by its key's kind (`Key.kind`) and converted as the
record holds it: a number to float, a path resolved (`paths.resolve_path`), a vector to a
list of floats. One small function per kind, in `KIND_CHECKS`; a wrong type raises
`SceneError` naming the file, section and key."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

from fruitcli.errors import SceneError, echo
from fruitcli.scene.key import NUM, Key, number
from fruitcli.scene.paths import resolve_path


class _Value:
    """The value being checked and where it stands (`where` "file: [section]", `key`)."""

    def __init__(self, where: str, key: str, value: Any, scene_path: Path, must_exist: bool):
        self.where, self.key, self.value = where, key, value
        self.scene_path, self.must_exist = scene_path, must_exist

    def fail(self, expected: str) -> NoReturn:
        raise SceneError(f"{self.where}.{self.key}: expected {expected}, got {echo(self.value)}")


def _str(v: _Value, spec: Key) -> Any:
    if not isinstance(v.value, str):
        v.fail("a string")
    return v.value


def _path(v: _Value, spec: Key) -> Any:
    if not isinstance(v.value, str) or not v.value:
        v.fail("a file path string")
    p = resolve_path(v.scene_path, v.value)
    if v.must_exist and not p.exists():
        raise SceneError(f"{v.where}.{v.key}: file not found: {v.value}")
    return p


def _bool(v: _Value, spec: Key) -> Any:
    if not isinstance(v.value, bool):
        v.fail("true or false")
    return v.value


def _int(v: _Value, spec: Key) -> Any:
    if isinstance(v.value, bool) or not isinstance(v.value, int):
        v.fail("an integer")
    return v.value


def _num(v: _Value, spec: Key) -> Any:
    value = v.value
    if isinstance(value, bool) or not isinstance(value, NUM) or not math.isfinite(value):
        v.fail("a finite number")
    return float(value)


def _range(v: _Value, spec: Key) -> Any:
    """A number >= 0, or [lo, hi] with 0 <= lo <= hi."""
    value = v.value
    if number(value) and value >= 0:
        return float(value)
    ok = isinstance(value, list) and len(value) == 2 and all(number(x) for x in value)
    if not ok or not 0 <= value[0] <= value[1]:
        v.fail("a number >= 0 or [lo, hi] with 0 <= lo <= hi")
    return [float(x) for x in value]


def _vector(v: _Value, spec: Key) -> Any:
    """vec2, vec3 or box: that many finite numbers; a box's mins at most its maxes."""
    n = {"vec2": 2, "vec3": 3, "box": 6}[spec.kind]
    value = v.value
    ok = isinstance(value, list) and len(value) == n
    ok = ok and all(isinstance(x, NUM) and not isinstance(x, bool) for x in value)
    if not ok or not all(math.isfinite(x) for x in value):
        v.fail(f"a list of {n} numbers")
    out = [float(x) for x in value]
    if spec.kind == "box" and any(out[a] > out[a + 3] for a in range(3)):
        v.fail("[xmin, ymin, zmin, xmax, ymax, zmax] with min <= max")
    return out


def _list(v: _Value, spec: Key) -> Any:
    if not isinstance(v.value, list):
        v.fail("a list")
    _check_count(v, spec)
    return v.value


def _table(v: _Value, spec: Key) -> Any:
    if not isinstance(v.value, dict):
        v.fail("a table {key = value}")
    _check_count(v, spec)
    return v.value


def _check_count(v: _Value, spec: Key) -> None:
    """At most `spec.max_items` entries in a list or table."""
    if spec.max_items is not None and len(v.value) > spec.max_items:
        raise SceneError(
            f"{v.where}.{v.key}: expected at most {spec.max_items:,} entries, got {len(v.value):,}"
        )


KIND_CHECKS: dict[str, Callable[[_Value, Key], Any]] = {
    "str": _str,
    "path": _path,
    "bool": _bool,
    "int": _int,
    "num": _num,
    "range": _range,
    "vec2": _vector,
    "vec3": _vector,
    "box": _vector,
    "list": _list,
    "table": _table,
}
"""Key kind -> its check, which returns the value as the record holds it."""


def check_kind(
    where: str, key: str, spec: Key, value: Any, scene_path: Path, must_exist: bool
) -> Any:
    """`value` checked against `spec.kind` and converted (a path resolved against
    `scene_path`, checked to exist when `must_exist`)."""
    return KIND_CHECKS[spec.kind](_Value(where, key, value, scene_path, must_exist), spec)
