"""A mesh file's units, one table (``[geometry].unit``, ``--unit``), and the largest body.

The scene schema's choices and bounds and the mesh loader (`load`) read it. This module
imports nothing, so the scene schema can read it.
"""

from __future__ import annotations

UNIT_TO_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0}
"""A mesh file's unit -> its length in mm."""
MAX_EXTENT_MM = 5000.0
"""A mesh larger than this (after its unit) is refused: a touch skin for a soft robot is
not 5 m across, so the unit is wrong (a mm file read with --unit m took minutes)."""
