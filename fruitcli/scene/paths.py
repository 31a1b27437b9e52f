"""Scene paths: a relative path is resolved against the scene file's folder, then
against the project root (the nearest parent holding `pyproject.toml`)."""

from __future__ import annotations

from pathlib import Path


def _project_root(start: Path) -> Path | None:
    """The nearest folder from `start` up holding `pyproject.toml` (None: none)."""
    for parent in [start, *start.parents]:
        if (parent / "pyproject.toml").exists():
            return parent
    return None


def resolve_path(scene_path: Path, value: str) -> Path:
    """Resolve a scene-relative path: scene folder first, then the project root."""
    p = Path(value).expanduser()
    if p.is_absolute():
        return p
    first = (scene_path.parent / p).resolve()
    if first.exists():
        return first
    root = _project_root(scene_path.parent.resolve())
    if root is not None and ((root / p).exists() or not first.parent.exists()):
        return (root / p).resolve()
    return first
