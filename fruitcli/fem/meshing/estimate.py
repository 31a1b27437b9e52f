"""A tet mesh's size told before gmsh runs: its element count from the body's volume and
[mesh].size_mm, the memory and the least time that count takes (mm, bytes, s).

Measured on the flat pad 40 x 40 x 10 mm at size 1 mm (16,000 mm^3): 68,054 tets, about
4.3 per size^3 of volume, in 15 s on a shared two-core machine, the gmsh process peaking
at 285 MB."""

from __future__ import annotations

import numpy as np

from fruitcli.errors import MeshError
from fruitcli.memory import require

TETS_PER_SIZE3 = 4.5
"""Tets gmsh makes per size_mm^3 of volume (4.3 measured, rounded up)."""

BYTES_PER_TET = 2000.0
"""Memory gmsh and the mesh arrays take per tet (bytes; 285 MB for 68,054 tets)."""

FASTEST_TETS_PER_S = 50_000.0
"""Tets per second no machine is expected to beat (ten times the measured rate), so a
mesh refused for its time could not have been made within the limit anyway."""


def shell_volume_mm3(shell: dict) -> float:
    """Volume (mm^3) enclosed by a shell's triangle surface (divergence theorem)."""
    v = np.asarray(shell["vertices"], float)[np.asarray(shell["faces"], np.int64)]
    return abs(float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum()) / 6.0)


def expected_tets(volume_mm3: float, size_mm: float) -> float:
    """About how many tets gmsh makes of `volume_mm3` at edge length `size_mm`."""
    return TETS_PER_SIZE3 * volume_mm3 / size_mm / size_mm / size_mm  # inf, never 1 / 0


def check_mesh_size(outer: dict, size_mm: float, time_limit_s: float, where: str) -> float:
    """Refuse, in one line naming `where` and [mesh].size_mm, a mesh of `outer` that would
    not fit in memory or could not be made within `time_limit_s`; returns the estimate."""
    volume = shell_volume_mm3(outer)
    tets = expected_tets(volume, size_mm)
    what = (
        f"{where}: [mesh].size_mm = {size_mm:g} on {outer['name']} ({volume:.4g} mm^3): "
        f"about {tets:.3g} tets"
    )
    require(tets * BYTES_PER_TET, what, MeshError)
    least_s = tets / FASTEST_TETS_PER_S
    if least_s > time_limit_s:
        raise MeshError(
            f"{what} take gmsh at least {least_s:.3g} s, more than [mesh].time_limit_s = "
            f"{time_limit_s:g} s; use a larger size_mm"
        )
    return tets
