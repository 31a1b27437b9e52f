"""The detection methods, one table: what each is called, how it finds its candidates and
what it adds (``[detection].method``, `fruit locate --method`, `fruit live`).

The scene schema's choices, the command line's choices and the reference docs read
`METHODS`; `frames_to_touches.detect` (batch) and `stream.Stream.step` (per frame) dispatch on
its fields. Adding a method is one module with its function and one entry here
(docs/howto/add-a-detection-method.md). This module imports nothing of the library (a
method's function is named by its module path and loaded when first used), so the scene
schema can read it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from importlib import import_module


@dataclass(frozen=True)
class Method:
    """A detection method.

    `find` is how touches are found: "" the paper's strongest-first N9 with zeroing (a
    compiled per-frame kernel), else ``"module:function"`` of a function
    ``f(flat, grid, threshold, floor, max_touches, footprint) -> Touches`` of the
    activation grids `flat` (N, cells) counts on `grid` (`detect.Grid`), taking the
    touches above `threshold` counts, at most `max_touches` per frame, with `floor`
    counts subtracted before weighting (0 unless `floor` is set here) and `footprint` the
    skin's `two_footprints.Footprint` (None unless `refine` is "fit2"). `refine` is what
    places a touch after that ("n9": its N9 centroid; "fit2": one or two footprints;
    "model": the skin's footprint fitted on the frame's taxels, `model_fit`)."""

    name: str
    doc: str
    find: str = ""
    floor: bool = False
    refine: str = "n9"

    def finder(self) -> Callable:
        """The function `find` names (imported on first use)."""
        return _load(self.find)


_HERE = "fruitcli.sensing.detection"

METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("n9", "the paper's sequential N9 centroid (default)"),
        Method("n9_floor", "N9 with [detection].noise_floor_counts subtracted", floor=True),
        Method("peaks", "N9 of every local maximum", find=f"{_HERE}.finders:peaks", floor=True),
        Method(
            "fit2",
            "two footprints of the [skin] fitted around each peak (fingers close together)",
            find=f"{_HERE}.finders:fit2",
            floor=True,
            refine="fit2",
        ),
        Method(
            "model",
            "the skin's footprint fitted to the taxels around each peak, on the frame's "
            "deformed taxels (N9 kept where the fit fails)",
            refine="model",
        ),
    )
}


def method_help() -> str:
    """One line per method, for --help and the schema's doc."""
    return "; ".join(f"{m.name}: {m.doc}" for m in METHODS.values())


@cache
def _load(ref: str) -> Callable:
    """The function ``"module:function"`` names (imported once)."""
    module, _, function = ref.partition(":")
    return getattr(import_module(module), function)
