"""The crossing's numbers under mesh refinement: C0, and per object the contact dC, the
footprint sigma and the gap decay, at three element sizes at the surface.

Units: mm, fF. The default Fruit's crossing (pitch 16 x 12 mm, cover 2 mm, yarn radius
0.6 mm, insulation 0.1 mm, eps_r 2.8, the default gaps), the objects meshed to their
surface (`CellSolver.conform`). Sizes: the default `crossing.SURFACE_SIZE_MM`, 0.8 and
0.6 times it (the far size and the column over the touch box follow it, the crossing's
own size and the yarns' do not; a coarser cell fails in gmsh: overlapping facets at the
yarns). The footprint sigma is fitted
to the contact row over the centre crossing's quarter of the table (offsets up to half a pitch, as
`equivalents.footprint_sigma_mm`), the gap decay under the crossing is the gap at
which dC falls to 1/e of contact. Prints each and the default's departure from the
finest (target: within 3 %).

    python tests/performance/skin_refinement.py
"""

from __future__ import annotations

import time

import numpy as np

from fruitcli.electrostatics import crossing, equivalents
from fruitcli.electrostatics.cell_mesh import mesh_cell
from fruitcli.electrostatics.touch_objects import OBJECTS

GAPS = (0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)
FACTORS = (1.0, 0.8, 0.6)
TARGET = 0.03


def numbers(factor: float) -> dict:
    size = crossing.SURFACE_SIZE_MM * factor
    spec = crossing.cell_spec(16.0, 12.0, 2.0, 0.6, 0.1, GAPS)
    spec = crossing.replace(spec, surface_size_mm=size)
    t0 = time.perf_counter()
    solver = crossing.CellSolver(mesh_cell(spec, 1, 900.0), 2.8)
    c0 = solver.crossings()
    out = {"c0_ff": float(c0[solver.centre])}
    xs, ys = crossing.positions_mm(16.0), crossing.positions_mm(12.0)
    for name in OBJECTS:
        under = np.array(
            [-(solver.object_crossings(name, 0, 0, g) - c0)[solver.centre] for g in GAPS]
        )
        row = np.array(
            [
                [-(solver.object_crossings(name, x, y, 0.0) - c0)[solver.centre] for y in ys]
                for x in xs
            ]
        )
        out[f"{name} contact dC"] = float(under[0])
        out[f"{name} sigma"] = equivalents.footprint_sigma_mm(xs, ys, row)
        out[f"{name} gap decay"] = equivalents.decay_gap_mm(np.array(GAPS), under, under[0] / np.e)
    print(
        f"surface {size:.2f} mm: {len(solver.mesh.tets)} tets ({time.perf_counter() - t0:.0f} s)",
        flush=True,
    )
    return out


def main() -> None:
    runs = [numbers(f) for f in FACTORS]
    print(
        f"{'':22s}"
        + "".join(f"{crossing.SURFACE_SIZE_MM * f:>10.2f}" for f in FACTORS)
        + "   default vs finest"
    )
    worst = 0.0
    for key in runs[0]:
        vals = [r[key] for r in runs]
        rel = abs(vals[0] - vals[-1]) / abs(vals[-1])
        worst = max(worst, rel)
        print(f"{key:22s}" + "".join(f"{v:10.3f}" for v in vals) + f"   {100 * rel:5.1f} %")
    print(f"largest departure at the default: {100 * worst:.1f} % (target {100 * TARGET:g} %)")


if __name__ == "__main__":
    main()
