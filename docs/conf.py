"""Sphinx configuration of the fruit documentation (`make docs`)."""

from __future__ import annotations

import sys
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as package_version
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

project = "fruit"
author = "The fruit developers"
copyright = "the fruit developers, GPL-3.0-or-later"
try:
    release = package_version("fruitcli")
except PackageNotFoundError:
    release = "unknown"
version = release

extensions = ["myst_parser"]
source_suffix = {".md": "markdown"}
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]
exclude_patterns = ["_build", "README.md", "data/*.md"]  # data/: fragments that pages include
html_theme = "alabaster"
html_title = f"fruit {release}"
html_static_path: list[str] = []
suppress_warnings: list[str] = []
nitpicky = True
