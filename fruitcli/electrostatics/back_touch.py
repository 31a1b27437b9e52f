"""A touch on either face of a thin pad: the crossing's drop with an object on the front
or on the back (paper Sec. V-A, Fig. 8 (c): a finger behind the bent 3 mm pad).

Units: mm, fF. The pad is `thickness_mm` of silicone with air on both sides (no ground
plane; the cell's outer faces insulate), its crossing `depth_mm` under the front face.
The table's cell (`crossing.cell_spec`) has 3 mm of silicone under the lower yarn and
an insulating face there; this cell ends the silicone at the pad's back.

A touch from the back is solved as one from the front of the mirrored pad: the crossing
`thickness_mm - depth_mm` under the touched face, the lower yarn (Tx) now the upper one.
The geometry's upper yarn is named Rx and runs along x, so the mirrored cell is also
turned a quarter turn (its pitches exchanged); the mutual capacitance is reciprocal
(the charge Rx draws with Tx at 1 V is the charge Tx draws with Rx at 1 V), so the
exchange of names does not change it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fruitcli.electrostatics import crossing
from fruitcli.electrostatics.cell_geometry import CellSpec

BACK_AIR_MM = 10.0
"""Air behind the pad (mm), as much as the table's cell has over its largest gap."""


@dataclass(frozen=True)
class Pad:
    """A pad's crossing (mm; permittivity relative)."""

    pitch_x_mm: float
    pitch_y_mm: float
    thickness_mm: float
    depth_mm: float  # the crossing under the front face
    yarn_radius_mm: float
    insulation_mm: float
    permittivity: float

    def check(self) -> None:
        """ValueError naming what does not fit: the two yarns and the insulation between
        them (two diameters and the insulation) must lie inside the pad."""
        half = 2 * self.yarn_radius_mm + self.insulation_mm / 2  # crossing to a yarn's far side
        room = (self.depth_mm - half, self.thickness_mm - self.depth_mm - half)
        if min(room) <= 0:
            raise ValueError(
                f"pad: the crossing {self.depth_mm:g} mm deep does not fit a "
                f"{self.thickness_mm:g} mm pad (the yarns reach {half:g} mm either side "
                f"of it); expected a depth in ({half:g}, {self.thickness_mm - half:g}) mm"
            )


def pad_spec(pad: Pad, side: str) -> CellSpec:
    """The cell of `pad` seen from `side` ("front" or "back"), the touched face at z = 0."""
    pad.check()
    if side not in ("front", "back"):
        raise ValueError(f"side: expected front or back, got {side!r}")
    depth = pad.depth_mm if side == "front" else pad.thickness_mm - pad.depth_mm
    px, py = (
        (pad.pitch_x_mm, pad.pitch_y_mm) if side == "front" else (pad.pitch_y_mm, pad.pitch_x_mm)
    )
    spec = crossing.cell_spec(px, py, depth, pad.yarn_radius_mm, pad.insulation_mm, [0.0])
    below = pad.thickness_mm - depth - 2 * pad.yarn_radius_mm - pad.insulation_mm / 2
    return replace(spec, below_mm=below, back_air_mm=BACK_AIR_MM)


def contact_drops_ff(
    pad: Pad, name: str = "finger", time_limit_s: float = 120.0
) -> dict[str, dict[str, float]]:
    """Per side ("front", "back"): {"c0": C0, "dc": dC} (fF) of the crossing, dC with
    object `name` touching that face over it (gap 0). The two C0 are of one pad meshed
    twice (mirrored): they differ by the discretization only."""
    from fruitcli.electrostatics.cell_mesh import mesh_cell

    out = {}
    for side in ("front", "back"):
        mesh = mesh_cell(pad_spec(pad, side), 1, time_limit_s)
        solver = crossing.CellSolver(mesh, pad.permittivity)
        c0 = solver.capacitance()
        dc = float(solver.object_crossings(name, 0.0, 0.0, 0.0)[solver.centre]) - c0
        if not np.isfinite(dc):
            raise ValueError(f"pad: the {side} touch's drop is not finite")
        out[side] = {"c0": c0, "dc": dc}
    return out


def bend_counts_per_ff(pad: Pad, time_limit_s: float = 120.0) -> tuple[float, dict[str, float]]:
    """(counts per fF, {"x": dC, "y": dC} fF) of the pad's own crossing bent as the
    paper's pad (`crossing.PAD_BEND_CURVATURE_PER_MM`, neutral plane `crossing.NEUTRAL_MM`
    under the front), fitted as `equivalents.counts_per_ff` fits a table: the larger
    bend shifts `crossing.BEND_SHIFT_COUNTS`. Solved on the one-crossing cell of the
    pad with its back face insulating (air behind it would be folded by the bend)."""
    from fruitcli.electrostatics.cell_mesh import mesh_cell

    spec = replace(crossing.deformation_spec(pad_spec(pad, "front")), back_air_mm=0.0)
    solver = crossing.CellSolver(mesh_cell(spec, 1, time_limit_s), pad.permittivity)
    c0 = solver.capacitance()
    _, _, curvatures, c_bend = crossing.deformation_table(solver, spec, c0)
    i = int(np.argmin(np.abs(curvatures - crossing.PAD_BEND_CURVATURE_PER_MM)))
    shift = c_bend[:, i] - c0
    return crossing.BEND_SHIFT_COUNTS / float(np.abs(shift).max()), {
        "x": float(shift[0]),
        "y": float(shift[1]),
    }
