"""Where the bundled scenes are and what they are called, below the scene schema (which
names them when a scene file given by a bundled scene's name is missing); reading and
copying them is `fruitcli.bundled`'s."""

from __future__ import annotations

import importlib.resources
from pathlib import Path

from fruitcli.errors import FruitError

SCENES = "pipelines"


def root() -> Path:
    """The folder holding `pipelines/` and `data/`: the package's copy, else the checkout's."""
    package = Path(str(importlib.resources.files("fruitcli")))
    for candidate in (package / "_bundled", package.parent):
        if (candidate / SCENES).is_dir():
            return candidate
    raise FruitError(f"{package}: the bundled scenes are missing (reinstall fruitcli)")


def scene_names() -> list[str]:
    """Names of the bundled scenes, sorted."""
    return sorted(p.stem for p in (root() / SCENES).glob("*.toml"))
