"""What a stage's hash takes from the scene: the values of the keys it declares it
reads, derived from the schema (`fruitcli.scene.SCHEMA`), so that a key added to a
section a stage reads is hashed without anyone listing it.

A declaration names whole sections ("material") or single keys ("geometry.unit"); a
whole section may leave keys out ("tracks" minus "tracks.file"). Every path key
(`Key.kind == "path"`, in tables and in arrays of tables) is hashed by the content of
the file it names, not by its path or time, and every section named by whether the scene
file declares it (`scene.has`: [gravity] applies only when declared).
"""

from __future__ import annotations

import hashlib
from collections.abc import Collection, Iterable
from pathlib import Path
from typing import Any

from fruitcli.scene import ARRAY_SCHEMA, ARRAY_SECTIONS, SCHEMA, Key, Scene

NESTED = {("geometry", "chamber"): "geometry.chamber"}
"""Table keys holding an array of tables, with the schema of one item."""


def file_hash(path: Path) -> str:
    """sha256 of a file's bytes, or of a folder's files (their paths inside it and their
    bytes, sorted by path)."""
    h = hashlib.sha256()
    path = Path(path)
    if path.is_dir():
        files = sorted(p for p in path.rglob("*") if p.is_file())
    else:
        files = [path]
    for p in files:
        if path.is_dir():
            h.update(p.relative_to(path).as_posix().encode() + b"\0")
        with open(p, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
    return h.hexdigest()


def content(path: Path | None) -> Any:
    """A file named by a scene key as hashed: its content's sha256 ("missing" when the
    file is not there yet, e.g. an artist mesh a stage generates)."""
    if path is None:
        return None
    return {"sha256": file_hash(path)} if Path(path).exists() else "missing"


def split(entry: str) -> tuple[str, str]:
    """("section", "key") of a declaration entry ("section" alone: key "")."""
    section, _, key = entry.partition(".")
    if section not in SCHEMA:
        raise ValueError(f"stage declaration {entry!r}: no section [{section}]")
    if key and (section in ARRAY_SECTIONS or key not in SCHEMA[section]):
        raise ValueError(f"stage declaration {entry!r}: no key {key!r} in [{section}]")
    return section, key


def covers(entries: Collection[str], section: str, key: str = "") -> bool:
    """True when the declaration `entries` names `section.key` (or its whole section);
    with key "" (the section itself, as `scene.has` reads it), when it names the section
    or any of its keys."""
    if section in entries or (key and f"{section}.{key}" in entries):
        return True
    return not key and any(e.startswith(f"{section}.") for e in entries)


def _hashed(spec: Key, value: Any, item_schema: dict[str, Key] | None) -> Any:
    if item_schema is not None:  # an array of tables: each item by its own schema
        return [{k: _hashed(item_schema[k], v, None) for k, v in item.items()} for item in value]
    if spec.kind == "path":
        return content(value)
    return value


def scene_inputs(scene: Scene, reads: Iterable[str], minus: Collection[str] = ()) -> dict:
    """The hashed scene inputs of a stage that reads `reads` (minus `minus`): each
    entry's values as plain data with files by content, and which of the sections named
    the scene file declares."""
    out: dict[str, Any] = {}
    sections = set()
    for entry in sorted(reads):
        section, key = split(entry)
        sections.add(section)
        values = scene.values(section)
        if section in ARRAY_SECTIONS:
            out[entry] = _hashed(Key("list"), values, ARRAY_SCHEMA[section])
            continue
        keys = [key] if key else [k for k in SCHEMA[section] if f"{section}.{k}" not in minus]
        out[entry] = {
            k: _hashed(
                SCHEMA[section][k],
                values[k],
                ARRAY_SCHEMA[NESTED[section, k]] if (section, k) in NESTED else None,
            )
            for k in keys
        }
    for entry in minus:
        split(entry)  # a misspelt exclusion is an error, not a silent no-op
    out["declared"] = sorted(s for s in sections if scene.has(s))
    return out
