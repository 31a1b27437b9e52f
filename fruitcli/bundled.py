"""The example scenes and the data they read, shipped inside the package.

A wheel holds the repository's top-level `pipelines/` and `data/` folders as
`fruitcli/_bundled/pipelines/` and `fruitcli/_bundled/data/` (pyproject.toml maps them
there), so a scene's relative paths such as `../data/paper/x.csv` resolve the same way
in an installed package as in a source checkout. A checkout is read in place.
"""

from __future__ import annotations

import re
import shutil
import tomllib
from pathlib import Path

from fruitcli.bundled_files import SCENES, root, scene_names
from fruitcli.errors import FruitError

__all__ = ["SCENES", "root", "scene_names"]  # re-exported: where the bundled files are


def scene_path(name: str) -> Path:
    """The bundled scene file called `name` (with or without `.toml`)."""
    name = name.removesuffix(".toml")
    path = root() / SCENES / f"{name}.toml"
    if not path.is_file():
        raise FruitError(f"unknown scene '{name}' (bundled scenes: {', '.join(scene_names())})")
    return path


def describe(path: Path) -> str:
    """One line on what a scene shows: [scene].description, else its first comment sentence."""
    text = path.read_text()
    description = tomllib.loads(text).get("scene", {}).get("description", "")
    if description:
        return description
    comment = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        comment.append(line.lstrip("#").strip())
    return _first_clause(" ".join(comment)) or path.stem


def _first_clause(text: str) -> str:
    """`text` up to its first colon or sentence end outside parentheses."""
    depth = 0
    for i, c in enumerate(text):
        depth += (c == "(") - (c == ")")
        if depth == 0 and (c == ":" or (c == "." and text[i + 1 : i + 3].strip()[:1].isupper())):
            return text[:i]
    return text.rstrip(".")


def _strings(node: object) -> list[str]:
    """Every string value in a parsed TOML document."""
    if isinstance(node, str):
        return [node]
    if isinstance(node, dict):
        return [s for v in node.values() for s in _strings(v)]
    if isinstance(node, list):
        return [s for v in node for s in _strings(v)]
    return []


def _quote_replace(text: str, old: str, new: str) -> str:
    """`text` with every TOML string literal equal to `old` (either quote) set to `new`."""
    pattern = re.compile(r"([\"'])" + re.escape(old) + r"\1")
    return pattern.sub(lambda m: f'"{new}"', text)


def export_scene(name: str, folder: Path) -> Path:
    """Write bundled scene `name` as `folder/NAME.toml` with the data files it reads
    (under `folder/`, paths rewritten to match). A generated artist mesh is written
    beside the scene. Existing files of the same names are replaced. Returns the scene."""
    from fruitcli.fsutil import atomic_path, write_text
    from fruitcli.scene import load_scene, parse_scene, resolve_path

    source = scene_path(name)
    base = root()
    text = source.read_text()
    raw = tomllib.loads(text)
    geometry = raw.get("geometry", {})
    generated = geometry.get("artist") if geometry.get("generate_artist") else None
    copies: dict[Path, Path] = {}  # source file -> path relative to folder
    for value in dict.fromkeys(_strings(raw)):
        if value == generated:
            text = _quote_replace(text, value, Path(value).name)
            continue
        found = resolve_path(source, value)
        if found.is_file() and found.is_relative_to(base):
            rel = found.relative_to(base)
            copies[found] = rel
            text = _quote_replace(text, value, rel.as_posix())
    target = Path(folder) / source.name
    parse_scene(text, target.resolve(), must_exist=False)  # the rewritten scene still parses
    for src, rel in copies.items():
        with atomic_path(Path(folder) / rel) as tmp:
            shutil.copyfile(src, tmp)
    write_text(target, text)
    load_scene(target)  # every file it names is where it says
    return target


def copy_scene(name: str, folder: Path) -> Path:
    """`export_scene` into a new or empty folder only: nothing existing is overwritten,
    and on failure nothing is left behind."""
    from fruitcli.fsutil import staged_dir

    folder = Path(folder)
    scene_path(name)  # an unknown name fails before anything is made
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        what = "is not a folder" if not folder.is_dir() else "is not empty"
        raise FruitError(f"{folder}: {what}; give a new or empty folder (nothing written)")
    with staged_dir(folder) as tmp:
        export_scene(name, tmp)
    return folder / f"{name.removesuffix('.toml')}.toml"
