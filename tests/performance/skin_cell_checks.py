"""How the small indenter's signal on the default crossing depends on the cell's
modelling choices: the mesh at the surface, the height of the air (how much of the
indenter's rod the cell holds) and a grounded against a floating indenter.

Units: mm, fF. The default Fruit's crossing (pitch 16 x 12 mm, cover 2 mm, yarn radius
0.6 mm, insulation 0.1 mm, eps_r 2.8) with node layers at the gaps 0, 1 and 2 mm; the
small indenter and the medium one centred over the crossing, each as the set of mesh
nodes inside it (not meshed to its surface as the table's objects are: these checks
compare choices on one mesh, not absolute drops). A floating indenter is an
equipotential with no net charge: with u1 (Tx 1 V, indenter 0 V) and u2 (Tx 0 V,
indenter 1 V), its potential is V = -Q_ind(u1) / Q_ind(u2) and C = -(Q_rx(u1) + V
Q_rx(u2)).

    python tests/performance/skin_cell_checks.py [SURFACE_MM [AIR_ABOVE_GAPS_MM]]

SURFACE_MM: the element size at the surface (default 0.8, `crossing.SURFACE_SIZE_MM`);
AIR_ABOVE_GAPS_MM: the air above the largest gap (default 10,
`crossing.OBJECT_LENGTH_MM`).
"""

from __future__ import annotations

import sys
import time

import numpy as np
import scipy.sparse.linalg as spl

from fruitcli.electrostatics import crossing
from fruitcli.electrostatics.cell_mesh import mesh_cell
from fruitcli.electrostatics.touch_objects import OBJECTS


def floating_dc(solver, obj: np.ndarray, c0: float) -> tuple[float, float]:
    """(dC fF, potential V) of the indenter's nodes `obj` left floating."""
    k = solver.k.tocsr()
    held = np.zeros(len(solver.mesh.nodes), bool)
    held[solver.fixed] = True
    held[obj] = True
    free = np.flatnonzero(~held)
    lu = spl.splu(k[free][:, free].tocsc())

    def solve(tx: float, ind: float) -> np.ndarray:
        u = np.zeros(len(solver.mesh.nodes))
        u[solver.tx] = tx
        u[obj] = ind
        u[free] = lu.solve(-(k[free] @ u))
        return u

    def charge(u, nodes):
        return float((k[nodes] @ u).sum())

    u1, u2 = solve(1.0, 0.0), solve(0.0, 1.0)
    v = -charge(u1, obj) / charge(u2, obj)
    return -(charge(u1, solver.rx) + v * charge(u2, solver.rx)) - c0, v


def main(argv: list[str]) -> None:
    crossing.SURFACE_SIZE_MM = float(argv[0]) if argv else crossing.SURFACE_SIZE_MM
    crossing.OBJECT_LENGTH_MM = float(argv[1]) if len(argv) > 1 else crossing.OBJECT_LENGTH_MM
    from fruitcli.studies.machine import machine_line

    print(machine_line())
    spec = crossing.cell_spec(16.0, 12.0, 2.0, 0.6, 0.1, (0.0, 1.0, 2.0))
    t0 = time.perf_counter()
    solver = crossing.CellSolver(mesh_cell(spec, 1, 600.0), 2.8)
    c0 = solver.capacitance()
    print(
        f"surface {crossing.SURFACE_SIZE_MM:g} mm, air {spec.air_mm:g} mm: "
        f"{len(solver.mesh.tets)} tets, C0 {c0:.1f} fF ({time.perf_counter() - t0:.0f} s)"
    )
    for name in ("small", "medium"):
        for gap in (0.0, 1.0, 2.0):
            obj = np.flatnonzero(OBJECTS[name].contains(solver.mesh.nodes, 0, 0, gap) & solver.air)
            line = (
                f"  {name} gap {gap:g} mm: {len(obj)} nodes, dC grounded "
                f"{solver.capacitance(obj) - c0:+.2f} fF"
            )
            if gap == 0.0:
                dc, v = floating_dc(solver, obj, c0)
                line += f", floating {dc:+.2f} fF (at {v:.3f} V)"
            print(line, flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
