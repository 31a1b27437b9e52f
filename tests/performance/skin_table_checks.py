"""How far interpolating the crossing's table moves a located touch, and how well the
3 x 3 crossings of the cell stand for one crossing in an endless skin.

Units: mm, fF. The default Fruit's crossing (pitch 16 x 12 mm, cover 2 mm, yarn radius
0.6 mm, insulation 0.1 mm, eps_r 2.8, the default gaps); at each gap of GAPS a table
twice as fine as the default (`crossing.STEPS_PER_HALF_PITCH`) is solved; the default
table is every other offset of it. For each object a touch at every fine position of
the quarter cell is located by the paper's N9 centroid over the 3 x 3 taxels around the
centre one (taxels 16 x 12 mm apart): once with the fine table's values (solved there)
and once with the default table interpolated there by the electrostatic skin
(`CrossingSkin.drop`). Prints the largest distance between the two located positions
(target: below 0.1 mm), and the largest difference between the two crossings that see
the same offset (the cell's departure from translation invariance).

    python tests/performance/skin_table_checks.py [FINE_TABLE.npz]

FINE_TABLE.npz: where to keep the fine table (dx, dy, dc).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from fruitcli.electrostatics import crossing
from fruitcli.electrostatics.cell_mesh import mesh_cell
from fruitcli.electrostatics.touch_objects import OBJECTS
from fruitcli.sensing.skin.crossing_skin import CrossingSkin

PITCH = (16.0, 12.0)
DESIGN = (2.0, 0.6, 0.1)  # cover, yarn radius, insulation (mm)
GAPS = (0.0, 1.0)
ALL_GAPS = (0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)
TARGET_MM = 0.1


def skin_of(dx, dy, gaps, dc) -> CrossingSkin:
    """The electrostatic skin of a touch table alone (1 count per fF)."""
    objects = list(OBJECTS)
    arrays = {
        "c0_ff": np.array(0.0),
        "objects": np.array(objects),
        "gap_mm": np.asarray(gaps, float),
        "dx_mm": dx,
        "dy_mm": dy,
        "dc_ff": dc,
        "strain": np.array([0.0, 0.1]),
        "curvature_per_mm": np.array([0.0, 0.1]),
        "c_stretch_ff": np.zeros((2, 2)),
        "c_bend_ff": np.zeros((2, 2)),
    }
    summary = {
        "counts_per_ff": 1.0,
        "objects": {n: {"gap_decay_mm": 1.0, "footprint_sigma_mm": 5.0} for n in objects},
    }
    return CrossingSkin.from_table(arrays, summary)


def n9(values: np.ndarray) -> np.ndarray:
    """(P, 2) N9 centroids of activations (P, 3, 3) of taxels (i px, j py), i, j in -1..1."""
    v = np.maximum(values, 0.0)
    w = v / v.sum(axis=(1, 2), keepdims=True)
    k = np.array([-1.0, 0.0, 1.0])
    return np.stack([(w.sum(axis=2) @ k) * PITCH[0], (w.sum(axis=1) @ k) * PITCH[1]], axis=1)


def main() -> None:
    fine = 2 * crossing.STEPS_PER_HALF_PITCH
    spec = crossing.cell_spec(*PITCH, *DESIGN, ALL_GAPS)
    t0 = time.perf_counter()
    solver = crossing.CellSolver(mesh_cell(spec, 1, 600.0), 2.8)
    c0 = solver.crossings()
    print(f"cell: {len(solver.mesh.tets)} tets ({time.perf_counter() - t0:.0f} s)")
    dx, dy, dc, mismatch = crossing.touch_table(
        solver, spec, list(OBJECTS), np.asarray(GAPS), c0, steps=fine
    )
    if len(sys.argv) > 1:
        np.savez(sys.argv[1], dx=dx, dy=dy, dc=dc)
    print(f"largest difference of two crossings at one offset: {mismatch:.2f} fF")
    coarse = skin_of(dx[::2], dy[::2], GAPS, dc[:, :, ::2, ::2])
    exact = skin_of(dx, dy, GAPS, dc)
    xs, ys = crossing.positions_mm(PITCH[0], fine), crossing.positions_mm(PITCH[1], fine)
    px, py = np.meshgrid(xs, ys, indexing="ij")
    px, py = px.ravel(), py.ravel()
    k = np.array([-1.0, 0.0, 1.0])
    off_x = px[:, None, None] - k[None, :, None] * PITCH[0]  # (P, 3, 3): touch - taxel
    off_y = py[:, None, None] - k[None, None, :] * PITCH[1]
    worst = 0.0
    for name in OBJECTS:
        for gap in GAPS:
            a = n9(exact.drop(name, off_x, off_y, gap))
            b = n9(coarse.drop(name, off_x, off_y, gap))
            moved = float(np.hypot(*(a - b).T).max())
            worst = max(worst, moved)
            print(f"  {name} gap {gap:g} mm: located positions moved by at most {moved:.3f} mm")
    print(f"largest: {worst:.3f} mm (target below {TARGET_MM:g} mm)")


if __name__ == "__main__":
    main()
