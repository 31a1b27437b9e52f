"""The ranges and conditions the scene schema's keys share: named bounds (mm, kPa, counts,
seconds), the most items a list or array may hold, and the `valid` conditions of keys
whose values a range cannot describe."""

from __future__ import annotations

import math
from typing import Any

from fruitcli.geometry.mesh.units import MAX_EXTENT_MM
from fruitcli.scene.key import number

Bounds = dict[str, Any]
"""A range (and its wording) several keys share, spread into `Key(..., **POSITIVE)`."""
POSITIVE: Bounds = {"min": 0.0, "min_exclusive": True}
SEED: Bounds = {"min": 0, "max": 2**63 - 1, "expected": "a seed 0 <= seed < 2^63"}
MAX_FACES = 10_000_000
"""Most triangles a reduced surface may ask for (a 10 M triangle surface is ~1 GB)."""
OPEN_FRACTION: Bounds = {"min": 0.0, "max": 1.0, "min_exclusive": True, "max_exclusive": True}
LENGTH: Bounds = {"min": 0.0, "max": MAX_EXTENT_MM}
"""A length in mm: no longer than the largest body (`geometry.mesh.load.MAX_EXTENT_MM`)."""
POSITIVE_LENGTH: Bounds = {**POSITIVE, "max": MAX_EXTENT_MM}
FAR_MM = 1e6
"""Farthest coordinate (mm) of a point or box: any body (at most MAX_EXTENT_MM across, near
the origin) and any box drawn around it fit within it."""
COORDINATE: Bounds = {"min": -FAR_MM, "max": FAR_MM}
ANGLE: Bounds = {"min": -360.0, "max": 360.0}
MAX_COUNTS = 65535
"""Largest CDC count a board reports (16-bit)."""
COUNTS: Bounds = {"min": 0.0, "max": MAX_COUNTS}
MAX_HEIGHT_FORM = 4.0
"""Largest weight or share of a crossing's height difference in the skin's footprint
([skin].height_as_distance, height_as_gap): the calibrated ones are 0-1."""
MAX_WIDENING_PER_MM = 1.0
"""Largest growth of the footprint's width per mm of gap ([skin].widening_per_mm): twice as
wide 1 mm away; an electrostatic crossing's calibrated growth is 0.02-0.07 per mm."""
MODULUS_KPA = 1e9
"""Largest modulus (kPa): 1 TPa, stiffer than any solid."""
PRESSURE_KPA = 1e5
"""Largest chamber pressure, either sign (kPa): 100 MPa, far past any silicone's burst."""
MAX_SECONDS = 1e6
"""Longest time budget or period (s): about 11 days."""
MAX_FRAMES = 10**8
MAX_MODEL_FRAMES = 60  # a second at the board's 60 frames/s
"""Most frames a key may ask for (a bench's idle frames are also sized by `memory`)."""
MAX_STATES = 10_000
"""Most actuation states (each one a quasi-static solve)."""
MAX_ITEMS = 1000
"""Most tables in an array ([[fixed]], [[geometry.chamber]], ...) and entries of a list."""
MAX_INDENTERS = 64
"""Most indenters a bench may replay, or [skin] may give a width."""
MAX_GRID_LINES = 10_000
"""Most taxels along one axis of a flat pad's grid (its rows are also sized by `memory`)."""


def plain_folder_name(name: str) -> bool:
    """A name usable as one folder (out/<name>): not blank, no separator, not . or ..."""
    return bool(name.strip()) and name not in (".", "..") and not any(c in name for c in "/\\")


def two_positive_ints(count: list) -> bool:
    """[nx, ny]: two integers 1 <= n <= MAX_GRID_LINES."""
    return len(count) == 2 and all(
        isinstance(c, int) and not isinstance(c, bool) and 0 < c <= MAX_GRID_LINES for c in count
    )


def increasing_pair(pair: list[float]) -> bool:
    """[lo, hi] with lo < hi."""
    return pair[0] < pair[1]


def nonzero_vector(v: list[float]) -> bool:
    """A vector of non-zero length."""
    return math.hypot(*v) != 0


def gap_table(gaps: Any) -> bool:
    """At least two finite gaps (mm), increasing from 0 (contact)."""
    return (
        isinstance(gaps, (list, tuple))
        and len(gaps) >= 2
        and all(number(g) and g <= MAX_EXTENT_MM for g in gaps)
        and gaps[0] == 0
        and all(b > a for a, b in zip(gaps[:-1], gaps[1:], strict=False))
    )


def nonempty_box(box: list[float]) -> bool:
    """[xmin, ymin, zmin, xmax, ymax, zmax] with each min < max."""
    return all(box[a] < box[a + 3] for a in range(3))
