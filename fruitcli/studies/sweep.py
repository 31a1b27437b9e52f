"""Design sweeps: a scene run for every combination (`grid`) or zipped lists (`zip`) of
scene values given as `KEY=V1,V2,...`, each variant validated like a scene file.

Keys are written as in the scene file, `section.key` (`mesh.size_mm`,
`material.poisson_ratio`, `grid.spacing_x_mm`); inside a table-valued key one more
part (`actuation.pressure_kpa.c1`, `geometry.chamber.c1.ellipsoid.radii_mm`). Chambers
are named by their `name` (or their number, from 1), other arrays of tables by number:
`jig.1.rotate_deg`, `fixed.1.box_mm`. `geometry.chamber.c1.radii_mm` is short for
`...c1.ellipsoid.radii_mm`. Values are TOML values (`3.5`, `true`, `"text"`,
`[10, 10, 4]`); a bare word or path is a string (`solver.linear_solver=pcg,direct`).
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import re
import tomllib
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from fruitcli.errors import FruitError
from fruitcli.scene import ARRAY_SCHEMA, ARRAY_SECTIONS, SCHEMA, SUBTABLES, Scene, parse_scene


class SweepError(FruitError):
    """A --set option, or a variant it makes, is malformed (names the option)."""


@dataclass(frozen=True)
class SetSpec:
    """One swept key and its values, in the order given."""

    key: str
    values: tuple


@dataclass
class Variant:
    """One combination of swept values: folder name, values by key, validated scene and
    the TOML text it was validated from (what a worker rebuilds it from)."""

    name: str
    values: dict
    scene: Scene
    text: str


BARE = re.compile(r"^[A-Za-z_./][A-Za-z0-9_./+-]*$")  # words and paths


def parse_set(option: str) -> SetSpec:
    """`KEY=V1,V2,...` -> SetSpec (values as TOML values, bare words as strings)."""
    key, eq, rhs = option.partition("=")
    key = key.strip()
    if not eq or not key:
        raise SweepError(f"--set {option!r}: expected KEY=V1,V2,... (e.g. mesh.size_mm=3,5)")
    items = _split_top(rhs)
    if not items or all(not i.strip() for i in items):
        raise SweepError(f"--set {key}: empty list of values (expected {key}=V1,V2,...)")
    values = []
    for item in items:
        item = item.strip()
        if not item:
            raise SweepError(f"--set {key}: empty value in {rhs!r}")
        values.append(_value(key, item))
    return SetSpec(key, tuple(values))


def _split_top(text: str) -> list[str]:
    """Split at commas outside brackets, braces and quotes."""
    out: list[str] = []
    cur: list[str] = []
    depth, quote = 0, ""
    for ch in text:
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            out.append("".join(cur))
            cur = []
            continue
        cur.append(ch)
    out.append("".join(cur))
    return out


def _value(key: str, item: str):
    try:
        return tomllib.loads(f"v = {item}")["v"]
    except tomllib.TOMLDecodeError:
        if BARE.match(item):
            return item
        raise SweepError(
            f"--set {key}: cannot read value {item!r} (a number, true/false, "
            'a word, a "quoted string" or a [list])'
        ) from None


def combinations(specs: list[SetSpec], mode: str = "grid") -> list[dict]:
    """Every combination of the specs' values (`grid`, first key slowest) or the i-th
    value of each (`zip`, all lists of one length); one dict key -> value each."""
    if not specs:
        raise SweepError("nothing to sweep: give at least one --set KEY=V1,V2,...")
    keys = [s.key for s in specs]
    dup = sorted({k for k in keys if keys.count(k) > 1})
    if dup:
        raise SweepError(f"--set {dup[0]}: given twice; put all its values in one --set")
    if mode == "zip":
        lengths = {s.key: len(s.values) for s in specs}
        if len(set(lengths.values())) > 1:
            listed = ", ".join(f"{k} has {n}" for k, n in lengths.items())
            raise SweepError(f"--zip needs lists of one length: {listed}")
        rows: Iterable[tuple] = zip(*(s.values for s in specs), strict=True)
    elif mode == "grid":
        rows = itertools.product(*(s.values for s in specs))
    else:
        raise SweepError(f"unknown sweep mode {mode!r} (grid or zip)")
    return [dict(zip(keys, r, strict=True)) for r in rows]


# ----------------------------------------------------------------------------- scene keys
def apply_value(raw: dict, key: str, value: object) -> None:
    """Set `key` (scene notation) to `value` in the raw TOML dict of a scene."""
    parts = key.split(".")
    section = parts[0]
    if section not in SCHEMA:
        raise SweepError(f"--set {key}: unknown section [{section}]{_closest(section, SCHEMA)}")
    if section == "geometry" and len(parts) > 1 and parts[1] == "chamber":
        items = raw.get("geometry", {}).get("chamber", [])
        items = [items] if isinstance(items, dict) else items
        target = _pick(
            key, "geometry.chamber", items, parts[2] if len(parts) > 2 else "", by_name=True
        )
        spec, rest = ARRAY_SCHEMA["geometry.chamber"], parts[3:]
        if len(rest) == 1 and rest[0] in SUBTABLES["ellipsoid"]:
            rest = ["ellipsoid", rest[0]]
    elif section in ARRAY_SECTIONS:
        items = raw.get(section, [])
        items = [items] if isinstance(items, dict) else items
        target = _pick(key, section, items, parts[1] if len(parts) > 1 else "")
        spec, rest = ARRAY_SCHEMA[section], parts[2:]
    else:
        target = raw.setdefault(section, {})
        if not isinstance(target, dict):
            raise SweepError(f"--set {key}: [{section}] in the scene is not a table")
        spec, rest = SCHEMA[section], parts[1:]
    if not rest:
        raise SweepError(f"--set {key}: name a key inside it (e.g. {key}.{next(iter(spec))})")
    name = rest[0]
    if name not in spec:
        raise SweepError(f"--set {key}: unknown key '{name}'{_closest(name, spec)}")
    if len(rest) == 1:
        target[name] = value
        return
    if name in SUBTABLES:
        sub = SUBTABLES[name]
        if len(rest) != 2 or rest[1] not in sub:
            raise SweepError(
                f"--set {key}: expected {'.'.join(parts[: -len(rest) + 1])}.<{' or '.join(sub)}>"
            )
    elif spec[name].kind != "table" or len(rest) != 2:
        plain = key.rsplit(".", len(rest) - 1)[0]
        raise SweepError(f"--set {key}: '{name}' is not a table; write {plain}=...")
    table = target.setdefault(name, {})
    if not isinstance(table, dict):
        raise SweepError(f"--set {key}: '{name}' in the scene is not a table")
    table[rest[1]] = value


def _pick(key: str, section: str, items: list, which: str, by_name: bool = False) -> dict:
    names = [str(i.get("name")) for i in items if isinstance(i, dict)] if by_name else []
    if which.isdigit() and 1 <= int(which) <= len(items):
        return items[int(which) - 1]
    if by_name and which in names:
        return items[names.index(which)]
    have = (
        f"chambers: {', '.join(names)}"
        if by_name and names
        else f"{len(items)} [[{section}]] table(s), numbered from 1"
    )
    what = "a chamber name or number" if by_name else "a number"
    raise SweepError(f"--set {key}: no [[{section}]] '{which}' ({what}; the scene has {have})")


def _closest(name: str, options: Iterable[str]) -> str:
    import difflib

    match = difflib.get_close_matches(name, list(options), n=1, cutoff=0.0)
    return f" (did you mean '{match[0]}'?)" if match else ""


def toml_text(raw: dict) -> str:
    """A TOML document of `raw`, every top-level entry one line `key = inline value`."""
    return "".join(f"{_toml_key(k)} = {_toml_value(v)}\n" for k, v in raw.items())


def _toml_key(key: str) -> str:
    return key if re.match(r"^[A-Za-z0-9_-]+$", key) else json.dumps(key)


def _toml_value(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + "}"
    raise SweepError(f"cannot write {type(value).__name__} into a scene")  # dates, times


# ----------------------------------------------------------------------------- variants
def fmt_value(value: object) -> str:
    """A value as it appears in folder names and tables: 3, 0.45, 10x10x4, pcg."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (int, float)):
        return (
            str(int(value))
            if float(value).is_integer() and abs(value) < 1e15
            else repr(float(value))
        )
    if isinstance(value, list):
        return "x".join(fmt_value(v) for v in value)
    if isinstance(value, dict):
        return "+".join(f"{k}-{fmt_value(v)}" for k, v in value.items())
    return str(value)


def short_labels(keys: list[str]) -> dict[str, str]:
    """The shortest dotted suffix of each key that tells it from the others."""
    out = {}
    for key in keys:
        parts = key.split(".")
        for n in range(1, len(parts) + 1):
            label = ".".join(parts[-n:])
            if sum(k == label or k.endswith("." + label) for k in keys) == 1:
                break
        out[key] = label
    return out


def variant_name(values: dict, labels: dict[str, str]) -> str:
    """Folder name from the values: `size_mm=3,poisson_ratio=0.45` (safe characters;
    long names shortened with a hash of the full one)."""
    name = ",".join(f"{labels[k]}={fmt_value(v)}" for k, v in values.items())
    safe = re.sub(r"[^A-Za-z0-9._=,+-]", "_", name)
    if safe != name or len(safe) > 120:
        digest = hashlib.sha1(name.encode()).hexdigest()[:8]
        safe = f"{safe[:100]}-{digest}"
    return safe


def build_variants(scene_path: Path, specs: list[SetSpec], mode: str = "grid") -> list[Variant]:
    """Every variant of the scene at `scene_path`, each validated like a scene file;
    the first bad key or value raises `SweepError` naming it (nothing has run)."""
    from fruitcli.errors import SceneError

    scene_path = Path(scene_path).resolve()
    try:
        raw0 = tomllib.loads(scene_path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise SceneError(f"{scene_path}: cannot read scene: {exc}") from None
    combos = combinations(specs, mode)
    labels = short_labels([s.key for s in specs])
    variants, names = [], set()
    for values in combos:
        raw = copy.deepcopy(raw0)
        for key, value in values.items():
            apply_value(raw, key, value)
        text = toml_text(raw)
        shown = ", ".join(f"{k}={fmt_value(v)}" for k, v in values.items())
        try:
            scene = parse_scene(text, scene_path)
        except SceneError as exc:
            raise SweepError(f"variant {shown}: {exc}") from None
        name = variant_name(values, labels)
        if name in names:
            raise SweepError(f"variant {shown}: given twice (each value once per --set)")
        names.add(name)
        variants.append(Variant(name, values, scene, text))
    return variants


def rebuild(text: str, scene_path: str | Path) -> Scene:
    """A variant's scene from its TOML text (on a worker; relative paths as the scene's)."""
    return parse_scene(text, Path(scene_path))
