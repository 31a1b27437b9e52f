"""The registration methods, one table (``[[evaluate]].register``, ``[bench].register``).

The scene schema's choices and `register` read `REGISTRATIONS`. This module imports
nothing, so the scene schema can read it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Registration:
    """A registration of measured points onto the truth: at least `min_samples` points,
    and whether top-view (x, y) data support it (`top_view`)."""

    name: str
    doc: str
    min_samples: int
    top_view: bool = False


REGISTRATIONS: dict[str, Registration] = {
    r.name: r
    for r in (
        Registration("none", "the measurement as it is", 0, top_view=True),
        Registration("translation", "the mean error vector removed", 1, top_view=True),
        Registration("rigid", "least-squares rotation and translation (Kabsch)", 3),
        Registration("similarity", "rotation, translation and one scale (Umeyama)", 3),
    )
}
