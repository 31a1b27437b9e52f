"""The detection methods, one table: what each is called, how it finds its candidates and
what it adds (``[detection].method``, `fruit locate --method`, `fruit live`).

The scene schema's choices, the command line's choices and the reference docs read
`METHODS`; `frames_to_touches.detect` and `Stream.step` dispatch on its fields. Adding a
method is one module with its function and one entry here. This module imports nothing,
so the scene schema can read it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Method:
    """A detection method: `extract` is how touches are found ("sequential": the paper's
    strongest-first N9 with zeroing; "peaks": every local maximum), `floor` whether
    ``noise_floor_counts`` is subtracted before weighting, `refine` what places a touch
    after that ("n9": its N9 centroid; "fit2": one or two footprints; "model": the skin's
    footprint fitted on the frame's taxels, `model_fit`)."""

    name: str
    doc: str
    extract: str = "sequential"
    floor: bool = False
    refine: str = "n9"


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("n9", "the paper's sequential N9 centroid (default)"),
        Method("n9_floor", "N9 with [detection].noise_floor_counts subtracted", floor=True),
        Method("peaks", "N9 of every local maximum", extract="peaks", floor=True),
        Method(
            "fit2",
            "two footprints of the [skin] fitted around each peak (fingers close together)",
            extract="peaks",
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
