"""Output folders that are the tool's own: a command writes only into a new folder, an
empty one, or one that fruit made itself, so a user's files are never overwritten.

fruit recognises its folders by the marker file `.fruit-output.json` it leaves in every
folder it creates or writes into, or by the planner's stage manifests
(`<stage>/manifest.json`, `<scene>/<stage>/manifest.json`) that folders written before
the marker existed hold.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator
from pathlib import Path

from fruitcli.errors import FruitError

MARKER = ".fruit-output.json"
IGNORED = {".DS_Store"}  # what a file browser leaves in any folder it showed


class OutputFolderError(FruitError):
    """An --out that is a file, not writable, or holds files fruit did not write."""


def _entries(folder: Path) -> list[Path]:
    return [p for p in folder.iterdir() if p.name not in IGNORED]


def _stage_manifest(path: Path) -> bool:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return False
    return isinstance(data, dict) and {"stage", "hash"} <= data.keys()


def is_own(folder: str | os.PathLike) -> bool:
    """True when `folder` is fruit's: it holds the marker, or a planner's stage manifest
    one or two levels down (a `fruit run` or `fruit demo` folder)."""
    folder = Path(folder)
    if (folder / MARKER).is_file():
        return True
    return any(_stage_manifest(p) for p in folder.glob("*/manifest.json")) or any(
        _stage_manifest(p) for p in folder.glob("*/*/manifest.json")
    )


def check(folder: str | os.PathLike, option: str = "--out") -> None:
    """Refuse, in one line and before anything is written, an output folder that is a
    file, cannot be written, or holds files fruit did not write."""
    folder = Path(folder)
    if folder.is_file() or (folder.exists() and not folder.is_dir()):
        raise OutputFolderError(
            f"{option} {folder}: is a file, not a folder; choose a new folder (nothing written)"
        )
    if not folder.exists():
        above = next((p for p in folder.parents if p.exists()), None)
        if above is not None and not above.is_dir():
            raise OutputFolderError(
                f"{option} {folder}: {above} is a file, not a folder; choose another "
                "folder (nothing written)"
            )
        return
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputFolderError(
            f"{option} {folder}: not writable; choose a folder you can write (nothing written)"
        )
    try:
        foreign = bool(_entries(folder)) and not is_own(folder)
    except OSError as exc:
        raise OutputFolderError(f"{option} {folder}: cannot be read ({exc.strerror})") from None
    if foreign:
        raise OutputFolderError(
            f"{option} {folder}: holds files fruit did not write; choose a new folder or "
            "empty it (nothing written)"
        )


def _mark(folder: Path, command: str) -> None:
    from fruitcli.fsutil import write_json

    if not (folder / MARKER).exists():
        write_json(folder / MARKER, {"written_by": "fruit", "first_command": command})


@contextlib.contextmanager
def claimed(
    folder: str | os.PathLike, command: str = "fruit", option: str = "--out"
) -> Iterator[Path]:
    """Check `folder` (see `check`), create it and its missing parents, each with the
    marker, and yield it. When the block wrote nothing into it (a bad input, a dry run),
    the marker and the folders made here are removed again."""
    folder = Path(folder)
    check(folder, option)
    made: list[Path] = []
    for parent in reversed([folder, *folder.parents]):
        if not parent.exists():
            try:
                parent.mkdir()
            except FileExistsError:  # another run made it meanwhile
                continue
            except OSError as exc:
                _unmake(made)
                where = "" if parent == folder else f" ({parent})"
                raise OutputFolderError(
                    f"{option} {folder}: cannot be created{where}: {exc.strerror}; choose "
                    "another folder"
                ) from None
            made.append(parent)
    had_marker = (folder / MARKER).exists()
    try:
        for parent in made:  # a folder fruit made is its own
            _mark(parent, command)
        _mark(folder, command)
    except OSError:
        _unmake(made)
        raise
    try:
        yield folder
    finally:
        _release(folder, command, made, had_marker)


def _release(folder: Path, command: str, made: list[Path], had_marker: bool) -> None:
    """After the command: keep the marker where it wrote something, else leave the
    folders as they were before."""
    try:
        wrote = any(p.name != MARKER for p in _entries(folder))
    except OSError:
        return
    with contextlib.suppress(OSError):
        if wrote:
            _mark(folder, command)  # removed meanwhile by a run that wrote nothing
        elif not had_marker:
            (folder / MARKER).unlink(missing_ok=True)
            _unmake(made)


def _unmake(made: list[Path]) -> None:
    """Remove the folders `made` (deepest first) that hold nothing but the marker."""
    for parent in reversed(made):
        with contextlib.suppress(OSError):
            if all(p.name == MARKER for p in parent.iterdir()):
                (parent / MARKER).unlink(missing_ok=True)
                parent.rmdir()
