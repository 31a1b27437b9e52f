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
    release = package_version("fruit-touch")
except PackageNotFoundError:
    release = "unknown"
version = release

extensions = ["myst_parser"]
source_suffix = {".md": "markdown"}
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]
exclude_patterns = ["_build", "README.md", "data/*.md"]  # data/: fragments that pages include
# Furo, the theme of many scientific Python projects; _static/fruit.css wraps code lines
# wider than its content column (none scrolls at 1280 px), each line of code in its own
# span (setup below) so that a wrapped line's continuation is indented under it.
html_theme = "furo"
html_title = f"fruit {release}"
html_static_path = ["_static"]
html_css_files = ["fruit.css"]
suppress_warnings: list[str] = []
nitpicky = True


def _line_spans(app) -> None:
    """Highlighted code with every line in a <span id="line-N">, for fruit.css."""
    from pygments.formatters import HtmlFormatter

    class LineSpans(HtmlFormatter):
        def __init__(self, **options) -> None:
            options.setdefault("linespans", "line")
            super().__init__(**options)

    highlighter = getattr(app.builder, "highlighter", None)
    if highlighter is not None and highlighter.dest == "html":
        highlighter.formatter = LineSpans


def setup(app) -> dict:
    app.connect("builder-inited", _line_spans)
    return {"parallel_read_safe": True}
