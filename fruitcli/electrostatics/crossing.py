"""One Tx-Rx crossing's capacitance, its change under a touching object and under
deformation (paper Sec. III-C, Figs. 4-5), from the electrostatics of the cell.

Units: mm, fF, counts. The cell (`cell_geometry`) is meshed once; the Tx yarn is driven
at 1 V, the Rx yarn, the neighbouring yarns and the object are grounded (a CDC holds
every line but the driven one at ground), and the mutual capacitance is the charge drawn
onto Rx. C0 is that without an object. An object (`touch_objects`) is the set of mesh
nodes inside it, so every position is solved on the same mesh and dC = C - C0 carries
no remeshing noise; positions are the table's (gap, dx, dy), computed on dx, dy >= 0 and
mirrored (the cell is symmetric in x and in y). C_delta is C0 of the cell's nodes
stretched or bent (`deform`).

Counts: v = -counts_per_ff * dC (a touch takes field from Rx: dC < 0, v > 0) and a
baseline shift -counts_per_ff * (C_delta - C0) (positive: towards a false touch).
counts_per_ff is the one calibrated number, fitted so that this crossing bent as the
paper's 4 x 4 pad (Fig. 9: 180 deg over its 48 mm active length, neutral plane half its
3 mm thickness under the surface) shifts by at most 10 counts (the larger of the shifts
bent along either yarn: the paper does not say which; `equivalents.counts_per_ff`);
everything else is predicted.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from fruitcli.electrostatics import assemble, capacitance, deform
from fruitcli.electrostatics.cell_geometry import CellSpec
from fruitcli.electrostatics.occ_mesh import TetMesh
from fruitcli.electrostatics.touch_objects import OBJECTS
from fruitcli.errors import SolverError
from fruitcli.fem.solver import pardiso

OBJECT_LENGTH_MM = 10.0
"""Air above the table's largest gap: the objects reach through it to the cell's top."""

OFFSETS_PER_SIDE = 2
"""Lateral offsets on each side of the crossing: 0, p/4 and p/2 for 2 (p: the pitch)."""

STRAINS = (0.05, 0.1, 0.2, 0.3)
"""Stretch along each yarn (the yarn's limit is 0.3)."""

PAD_BEND_CURVATURE_PER_MM = np.pi / 48.0
"""The paper's bent pad (Fig. 9): 180 deg over its 48 mm active length."""

CURVATURES_PER_MM = (0.02, 0.04, PAD_BEND_CURVATURE_PER_MM)
"""Bend along each yarn, up to the bent pad's curvature."""

NEUTRAL_MM = 1.5
"""Depth of the neutral plane when bent: half the 3 mm pad of Fig. 9."""

BEND_SHIFT_COUNTS = 10.0
"""Fig. 9: the bent pad's largest baseline shift (counts): the calibration point."""

THRESHOLD_COUNTS = 20.0
"""The paper's touch threshold (counts), for the gap at which it is crossed."""

CROSSING_SIZE_RANGE = (0.1, 1.0 / 6.0)
"""Element size at the crossing as a fraction of the yarn radius: the insulation's
thickness clipped to this range (finer would not mesh in time, coarser misses the gap)."""

SURFACE_SIZE_MM = 0.8
"""Element size at the surface near the crossing, where the objects come (mm)."""


@dataclass
class CrossingTable:
    """The crossing's capacitances (fF) and the counts they make."""

    c0_ff: float
    objects: list[str]
    gap_mm: np.ndarray  # (g,)
    dx_mm: np.ndarray  # (x,)
    dy_mm: np.ndarray  # (y,)
    dc_ff: np.ndarray  # (k, g, x, y)
    deformations: list[str]  # stretch_x, stretch_y, bend_x, bend_y
    strain: np.ndarray  # (s,) with 0 first
    curvature_per_mm: np.ndarray  # (c,) with 0 first
    c_stretch_ff: np.ndarray  # (2, s): along x (the Rx yarn), along y (the Tx yarn)
    c_bend_ff: np.ndarray  # (2, c): curving along x, along y
    times_s: dict = field(default_factory=dict)
    mesh_info: dict = field(default_factory=dict)


def cell_spec(
    pitch_x_mm: float,
    pitch_y_mm: float,
    cover_mm: float,
    yarn_radius_mm: float,
    insulation_mm: float,
    gaps_mm,
) -> CellSpec:
    """The cell of a design, with the mesh sizes this module uses: a node layer at each
    of the table's gaps and a node at each tip position (dx, dy >= 0), so an object's
    lowest point is a node at every position of the table."""
    lo, hi = CROSSING_SIZE_RANGE
    size = float(np.clip(insulation_mm, lo * yarn_radius_mm, hi * yarn_radius_mm))
    gaps = [float(g) for g in gaps_mm]
    xs = offsets_mm(pitch_x_mm)
    ys = offsets_mm(pitch_y_mm)
    points = tuple((float(x), float(y), g) for g in gaps for x in xs[xs >= 0] for y in ys[ys >= 0])
    return CellSpec(
        pitch_x_mm,
        pitch_y_mm,
        cover_mm,
        yarn_radius_mm,
        insulation_mm,
        max(gaps) + OBJECT_LENGTH_MM,
        size,
        SURFACE_SIZE_MM,
        tuple(g for g in gaps if g > 0),
        points,
    )


def offsets_mm(pitch_mm: float) -> np.ndarray:
    """Lateral offsets across the cell, both signs: (2 OFFSETS_PER_SIDE + 1,)."""
    half = np.linspace(0.0, pitch_mm / 2, OFFSETS_PER_SIDE + 1)
    return np.concatenate([-half[:0:-1], half])


class CellSolver:
    """The cell's mesh, stiffness and conductors; C for any object position or node
    placement.

    Every solve is over the same unknowns (the nodes off the yarns) with the same
    sparsity pattern: an object's nodes are held at 0 V by replacing their rows and
    columns with the diagonal (kept as explicit zeros), so MKL PARDISO's analysis is done
    once and each position costs a numerical refactorization and one solve
    (`fruitcli.fem.solver.pardiso`; without MKL, a fresh Cholesky per solve)."""

    def __init__(self, mesh: TetMesh, permittivity: float):
        self.mesh = mesh
        regions = np.array(mesh.regions)[mesh.region]
        self.eps = np.where(regions == "silicone", permittivity, 1.0)
        self.tx = mesh.surfaces["tx"]
        self.rx = mesh.surfaces["rx"]
        sides = np.concatenate([mesh.surfaces["tx_side"], mesh.surfaces["rx_side"]])
        n = len(mesh.nodes)
        self.u_fixed = np.zeros(n)
        self.u_fixed[self.tx] = 1.0
        held = np.zeros(n, bool)
        held[np.concatenate([self.tx, self.rx, sides])] = True
        self.free = np.flatnonzero(~held)
        self.fixed = np.flatnonzero(held)
        self.air = np.zeros(n, bool)
        self.air[np.unique(mesh.tets[regions == "air"])] = True
        self._factor = None
        self._set_nodes(mesh.nodes)

    def _set_nodes(self, nodes) -> None:
        """Assemble on `nodes` (the mesh's, or moved) and split free and fixed parts."""
        try:
            k = assemble.stiffness(nodes, self.mesh.tets, self.eps, self.mesh.order)
        except ValueError as exc:
            raise SolverError(f"crossing cell: {exc} (deformed too far?)") from None
        self.k = k
        self.rhs = -(k[self.free][:, self.fixed] @ self.u_fixed[self.fixed])
        upper = sp.triu(k[self.free][:, self.free]).tocsr()
        upper.sort_indices()
        self.upper = upper
        self.row = np.repeat(np.arange(upper.shape[0]), np.diff(upper.indptr))

    def _solve(self, held_free: np.ndarray) -> np.ndarray:
        """Potentials (N,) with the free nodes `held_free` (mask over `free`) at 0 V."""
        data = self.upper.data.copy()
        off = (held_free[self.row] | held_free[self.upper.indices]) & (
            self.row != self.upper.indices
        )
        data[off] = 0.0
        rhs = np.where(held_free, 0.0, self.rhs)
        a = sp.csr_matrix((data, self.upper.indices, self.upper.indptr), self.upper.shape)
        if pardiso.available():
            self._factor = pardiso.factorize_upper(a, self._factor)
            x = self._factor.solve(rhs)
        else:  # without the optional extra `pardiso` (no MKL)
            full = (a + sp.triu(a, 1).T).tocsr()
            x = capacitance.factorized(full)(rhs)
        if not np.all(np.isfinite(x)):
            raise SolverError("crossing cell: the potential is not finite")
        u = self.u_fixed.copy()
        u[self.free] = x
        return u

    def capacitance(self, grounded=None, nodes=None) -> float:
        """Tx-Rx mutual capacitance (fF) with extra `grounded` nodes (off the yarns), on
        the mesh's nodes or on moved `nodes` (which then stay in use)."""
        if nodes is not None:
            self._set_nodes(nodes)
        held = np.zeros(len(self.mesh.nodes), bool)
        if grounded is not None:
            held[grounded] = True
        u = self._solve(held[self.free])
        return -capacitance.conductor_charge(self.k, u, self.rx)

    def with_object(self, name: str, dx: float, dy: float, gap: float) -> float:
        inside = OBJECTS[name].contains(self.mesh.nodes, dx, dy, gap) & self.air
        return self.capacitance(np.flatnonzero(inside))


def touch_table(solver: CellSolver, objects, gaps, dx, dy, c0: float, progress=None) -> np.ndarray:
    """dC (k, g, x, y) fF over the table, solved on dx, dy >= 0 and mirrored."""
    dx, dy = np.asarray(dx, float), np.asarray(dy, float)
    out = np.full((len(objects), len(gaps), len(dx), len(dy)), np.nan)
    ix = {v: i for i, v in enumerate(np.abs(dx))}  # |offset| -> a column holding it
    iy = {v: i for i, v in enumerate(np.abs(dy))}
    for k, name in enumerate(objects):
        for g, gap in enumerate(gaps):
            for ax in sorted(set(np.abs(dx))):
                for ay in sorted(set(np.abs(dy))):
                    out[k, g, ix[ax], iy[ay]] = solver.with_object(name, ax, ay, gap) - c0
            if progress is not None:
                progress(f"{name}: gap {gap:g} mm done")
    src_x = np.array([ix[abs(v)] for v in dx])
    src_y = np.array([iy[abs(v)] for v in dy])
    return out[:, :, src_x][:, :, :, src_y]


def deformation_table(
    solver: CellSolver, spec: CellSpec, c0: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(c_stretch (2, s), c_bend (2, c)) fF, strain and curvature lists with 0 first."""
    nodes = solver.mesh.nodes
    glue = 2 * spec.yarn_radius_mm + spec.insulation_mm
    ramp = min(spec.pitch_x_mm, spec.pitch_y_mm) / 2
    strains = np.array([0.0, *STRAINS])
    curvatures = np.array([0.0, *CURVATURES_PER_MM])
    c_stretch = np.full((2, len(strains)), c0)
    c_bend = np.full((2, len(curvatures)), c0)
    for a, axis in enumerate(("x", "y")):
        for i, s in enumerate(strains[1:], 1):
            moved = deform.deformed(nodes, deform.stretched(nodes, axis, s), glue, ramp)
            c_stretch[a, i] = solver.capacitance(nodes=moved)
        for i, kappa in enumerate(curvatures[1:], 1):
            moved = deform.deformed(nodes, deform.bent(nodes, axis, kappa, NEUTRAL_MM), glue, ramp)
            c_bend[a, i] = solver.capacitance(nodes=moved)
    solver.capacitance(nodes=nodes)  # back to the cell at rest
    return strains, c_stretch, curvatures, c_bend


def compute(
    spec: CellSpec,
    permittivity: float,
    gaps_mm,
    objects=tuple(OBJECTS),
    order: int = 1,
    time_limit_s: float = 120.0,
    progress=None,
) -> CrossingTable:
    """The crossing's table for a cell (`cell_spec`); gmsh is killed after time_limit_s."""
    from fruitcli.electrostatics.cell_mesh import mesh_cell

    t0 = time.perf_counter()
    mesh = mesh_cell(spec, order, time_limit_s)
    t_mesh = time.perf_counter() - t0
    if progress is not None:
        progress(f"cell meshed: {len(mesh.tets)} tets, {len(mesh.nodes)} nodes")
    t1 = time.perf_counter()
    solver = CellSolver(mesh, permittivity)
    c0 = solver.capacitance()
    dx, dy = offsets_mm(spec.pitch_x_mm), offsets_mm(spec.pitch_y_mm)
    gaps = np.asarray(gaps_mm, float)
    dc = touch_table(solver, list(objects), gaps, dx, dy, c0, progress)
    strains, c_stretch, curvatures, c_bend = deformation_table(solver, spec, c0)
    t_solve = time.perf_counter() - t1
    return CrossingTable(
        c0,
        list(objects),
        gaps,
        dx,
        dy,
        dc,
        ["stretch_x", "stretch_y", "bend_x", "bend_y"],
        strains,
        curvatures,
        c_stretch,
        c_bend,
        {"mesh_s": t_mesh, "solve_s": t_solve},
        {"tets": int(len(mesh.tets)), "nodes": int(len(mesh.nodes)), "order": order},
    )
