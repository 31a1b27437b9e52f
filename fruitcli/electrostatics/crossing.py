"""One Tx-Rx crossing's capacitance, its change under a touching object and under
deformation (paper Sec. III-C, Figs. 4-5), from the electrostatics of the cell.

Units: mm, fF, counts. The cell (`cell_geometry`) holds 3 x 3 crossings and is meshed
once; each Tx yarn inside it is driven at 1 V in turn, every other yarn and the object
grounded (a CDC holds every line but the driven one at ground), and each crossing's
mutual capacitance is the charge drawn onto its Rx yarn. C0 is that without an object.
An object (`touch_objects`) is a conductor meshed to its surface by moving the air nodes
next to it onto it (`CellSolver.conform`), so every position is solved on the same mesh
and pattern; the object visits the quarter cell next to the centre crossing and the
nine crossings give the table's offsets out to TABLE_PITCHES pitches (`touch_table`),
mirrored (the cell is symmetric in x and in y). C_delta is C0 of the one-crossing cell's
nodes stretched or bent (`deform`).

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
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from fruitcli.electrostatics import assemble, capacitance, deform
from fruitcli.electrostatics.cell_geometry import CellSpec
from fruitcli.electrostatics.occ_mesh import TetMesh
from fruitcli.electrostatics.touch_objects import INSIDE_TOL_MM, OBJECTS, nearest_on_surface
from fruitcli.errors import SolverError
from fruitcli.fem.solver import pardiso

if TYPE_CHECKING:
    from fruitcli.electrostatics.touch_objects import TouchObject

OBJECT_LENGTH_MM = 10.0
"""Air above the table's largest gap: the objects reach through it to the cell's top."""

SNAP_FRACTION = 0.45
"""An air node closer to an object's surface than this fraction of its shortest edge is
moved onto it (`CellSolver.conform`)."""

KEEP_VOLUME = 0.1
"""A node is not moved when a tet at it would keep less than this fraction of its volume."""

REACH_PITCHES = 2
"""The cell spans this many pitches either side of the centre crossing: 3 x 3 crossings
inside it, the yarns at 2 pitches on its side faces."""

STEPS_PER_HALF_PITCH = 2
"""Indenter positions across half a pitch (the quarter cell the indenter visits): the
table's offset step is half a pitch over this (4 mm and 3 mm on the Fruit: 2 and 1.5)."""

TABLE_PITCHES = 1.5
"""The table's offsets reach this many pitches either side (each neighbour of an N9
window and the ring beyond it)."""

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
"""Element size at the surface near the crossing (mm); over the quarter cell the objects
visit, a fraction of it (`cell_geometry.CONTACT_SIZE_FACTOR`, `COLUMN_SIZE_FACTOR`)."""


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
    gaps_mm: Sequence[float] | np.ndarray,
) -> CellSpec:
    """The cell of a design, with the mesh sizes this module uses and a node layer at
    each of the table's gaps (the objects are meshed to their surface by moving nodes:
    `CellSolver.conform`)."""
    lo, hi = CROSSING_SIZE_RANGE
    size = float(np.clip(insulation_mm, lo * yarn_radius_mm, hi * yarn_radius_mm))
    gaps = [float(g) for g in gaps_mm]
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
        (),
        REACH_PITCHES,
        (pitch_x_mm / 2, pitch_y_mm / 2),
    )


def deformation_spec(spec: CellSpec) -> CellSpec:
    """The one-crossing cell of `spec`'s design, for the deformations (no objects)."""
    return replace(spec, levels_mm=(), points_mm=(), reach=1, touch_box_mm=(0.0, 0.0))


def positions_mm(pitch_mm: float, steps: int | None = None) -> np.ndarray:
    """The indenter's positions from the centre crossing across half a pitch in `steps`
    (default STEPS_PER_HALF_PITCH) (mm)."""
    return np.linspace(0.0, pitch_mm / 2, (steps or STEPS_PER_HALF_PITCH) + 1)


def offsets_mm(pitch_mm: float, steps: int | None = None) -> np.ndarray:
    """The table's offsets, both signs, out to TABLE_PITCHES pitches (mm)."""
    step = pitch_mm / 2 / (steps or STEPS_PER_HALF_PITCH)
    n = round(TABLE_PITCHES * pitch_mm / step)
    return step * np.arange(-n, n + 1)


class CellSolver:
    """The cell's mesh, stiffness and conductors; the crossings' C for any object position
    or node placement.

    Each Tx yarn inside the cell is driven at 1 V in turn (every other yarn and the
    object at 0 V): one factorization, a right-hand side per Tx, and the charge on each
    Rx yarn is the mutual capacitance of that crossing. Every solve is over the same
    unknowns (the nodes off the yarns) with the same sparsity pattern: an object's nodes
    are held at 0 V by replacing their rows and columns with the diagonal (kept as
    explicit zeros), so MKL PARDISO's analysis is done once and each position costs a
    numerical refactorization (`fruitcli.fem.solver.pardiso`; without MKL, a fresh
    Cholesky per solve)."""

    def __init__(
        self, mesh: TetMesh, permittivity: float, objects: Mapping[str, TouchObject] | None = None
    ):
        self.mesh = mesh
        self.objects = OBJECTS if objects is None else objects  # name -> TouchObject
        regions = np.array(mesh.regions)[mesh.region]
        self.eps = np.where(regions == "silicone", permittivity, 1.0)
        names = sorted(mesh.surfaces, key=_yarn_order)
        self.tx_names = [k for k in names if k == "tx" or k[:3] in ("tx+", "tx-")]
        self.rx_names = [k for k in names if k == "rx" or k[:3] in ("rx+", "rx-")]
        self.tx = mesh.surfaces["tx"]
        self.rx = mesh.surfaces["rx"]
        self.centre = (self.tx_names.index("tx"), self.rx_names.index("rx"))
        yarns = [mesh.surfaces[k] for k in (*self.tx_names, *self.rx_names)]
        sides = np.concatenate([mesh.surfaces["tx_side"], mesh.surfaces["rx_side"], *yarns])
        n = len(mesh.nodes)
        self.u_fixed = np.zeros((len(self.tx_names), n))
        for i, name in enumerate(self.tx_names):
            self.u_fixed[i, mesh.surfaces[name]] = 1.0
        held = np.zeros(n, bool)
        held[sides] = True
        self.free = np.flatnonzero(~held)
        self.fixed = np.flatnonzero(held)
        self.air = np.zeros(n, bool)
        self.air[np.unique(mesh.tets[regions == "air"])] = True
        self._factor: pardiso.Pardiso | None = None
        self._set_nodes(mesh.nodes)
        self._conform_setup()

    def _conform_setup(self) -> None:
        """What `object_crossings` needs: each node's shortest edge, the tets at each
        node, every tet's entries' places in the upper triangle's data."""
        nodes, tets = self.mesh.nodes, self.mesh.tets[:, :4]
        pairs = np.array([(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)])
        a, b = tets[:, pairs[:, 0]].ravel(), tets[:, pairs[:, 1]].ravel()
        length = np.linalg.norm(nodes[a] - nodes[b], axis=1)
        self.edge_mm = np.full(len(nodes), np.inf)
        np.minimum.at(self.edge_mm, a, length)
        np.minimum.at(self.edge_mm, b, length)
        m = len(tets)
        self.node_tets = sp.csr_matrix(
            (np.ones(4 * m), (tets.ravel(), np.repeat(np.arange(m), 4))), (len(nodes), m)
        )
        self.free_at = np.full(len(nodes), -1)
        self.free_at[self.free] = np.arange(len(self.free))
        n_free = len(self.free)
        self.upper_keys = self.row.astype(np.int64) * n_free + self.upper.indices
        self.tet_eps = assemble.EPS0_FF_PER_MM * self.eps

    def conform(self, name: str, dx: float, dy: float, gap: float) -> tuple:
        """(held nodes, moved nodes, their positions (mm)) of object `name` with its tip at
        (dx, dy, gap) as a conductor meshed to its surface: air nodes closer to its
        surface than SNAP_FRACTION of their shortest edge are moved onto it (not those
        on the skin's surface, which stay in its plane; none that would flatten a tet
        below KEEP_VOLUME of its volume), and every node inside or on it is held."""
        obj = self.objects[name]
        nodes = self.mesh.nodes
        tol = 1e-9
        lifted = self.air & (nodes[:, 2] > tol)
        signed, near = nearest_on_surface(obj, nodes, dx, dy, gap)
        snap = lifted & (np.abs(signed) < SNAP_FRACTION * self.edge_mm)
        inside = self.air & (signed <= INSIDE_TOL_MM)
        tets = self.mesh.tets[:, :4]
        moved = np.flatnonzero(snap)
        for _ in range(8):
            at = nodes.copy()
            at[moved] = near[moved]
            hit = np.unique(self.node_tets[moved].indices)
            keep = _volumes(at, tets[hit]) > KEEP_VOLUME * _volumes(nodes, tets[hit])
            if keep.all():
                break
            bad = np.intersect1d(tets[hit[~keep]].ravel(), moved)
            moved = np.setdiff1d(moved, bad)
        held = np.flatnonzero(inside | np.isin(np.arange(len(nodes)), moved))
        return held, moved, near[moved]

    def object_crossings(self, name: str, dx: float, dy: float, gap: float) -> np.ndarray:
        """(tx, rx) C (fF) of the crossings with object `name` at (dx, dy, gap) meshed to
        its surface (`conform`): the stiffness of the tets at the moved nodes is
        assembled anew on the same pattern."""
        held, moved, where = self.conform(name, dx, dy, gap)
        data = self.upper.data.copy()
        if moved.size:
            tets = self.mesh.tets[np.unique(self.node_tets[moved].indices)]
            at = self.mesh.nodes.copy()
            at[moved] = where
            change = assemble.element_stiffness(at, tets) - assemble.element_stiffness(
                self.mesh.nodes, tets
            )
            change *= self.tet_eps[np.unique(self.node_tets[moved].indices)][:, None, None]
            fi = self.free_at[tets]  # (t, 4)
            r, c = fi[:, :, None], fi[:, None, :]
            use = (r >= 0) & (c >= 0) & (r <= c)
            r, c = np.broadcast_to(r, use.shape)[use], np.broadcast_to(c, use.shape)[use]
            place = np.searchsorted(self.upper_keys, r.astype(np.int64) * len(self.free) + c)
            np.add.at(data, place, change[use])
        held_mask = np.zeros(len(self.mesh.nodes), bool)
        held_mask[held] = True
        u = self._solve(held_mask[self.free], data)
        return -(self.k_rx @ u).T

    def _set_nodes(self, nodes: np.ndarray) -> None:
        """Assemble on `nodes` (the mesh's, or moved) and split free and fixed parts."""
        try:
            k = assemble.stiffness(nodes, self.mesh.tets, self.eps, self.mesh.order)
        except ValueError as exc:
            raise SolverError(f"crossing cell: {exc} (deformed too far?)") from None
        self.k = k
        self.rhs = -(k[self.free][:, self.fixed] @ self.u_fixed[:, self.fixed].T)
        self.k_rx = np.vstack(
            [np.asarray(k[self.mesh.surfaces[name]].sum(axis=0)).ravel() for name in self.rx_names]
        )  # (rx, N): the charge on each Rx yarn is this times u
        upper = sp.triu(k[self.free][:, self.free]).tocsr()
        upper.sort_indices()
        self.upper = upper
        self.row = np.repeat(np.arange(upper.shape[0]), np.diff(upper.indptr))

    def _solve(self, held_free: np.ndarray, data: np.ndarray | None = None) -> np.ndarray:
        """Potentials (N, tx) with the free nodes `held_free` (mask over `free`) at 0 V,
        one column per driven Tx yarn; `data`: the upper triangle's values when not the
        cell's own (a moved object's tets)."""
        data = (self.upper.data if data is None else data).copy()
        off = (held_free[self.row] | held_free[self.upper.indices]) & (
            self.row != self.upper.indices
        )
        data[off] = 0.0
        rhs = np.where(held_free[:, None], 0.0, self.rhs)
        a = sp.csr_matrix((data, self.upper.indices, self.upper.indptr), self.upper.shape)
        if pardiso.available():
            self._factor = pardiso.factorize_upper(a, self._factor)
            x = self._factor.solve(rhs)
        else:  # without the optional extra `pardiso` (no MKL)
            full = (a + sp.triu(a, 1).T).tocsr()
            solve = capacitance.factorized(full)
            x = np.column_stack([solve(b) for b in rhs.T])
        if not np.all(np.isfinite(x)):
            raise SolverError("crossing cell: the potential is not finite")
        u = self.u_fixed.T.copy()
        u[self.free] = x
        return u

    def crossings(
        self, grounded: np.ndarray | None = None, nodes: np.ndarray | None = None
    ) -> np.ndarray:
        """(tx, rx) mutual capacitances (fF) of the cell's crossings with extra `grounded`
        nodes (off the yarns), on the mesh's nodes or on moved `nodes` (which then stay
        in use)."""
        if nodes is not None:
            self._set_nodes(nodes)
        held = np.zeros(len(self.mesh.nodes), bool)
        if grounded is not None:
            held[grounded] = True
        u = self._solve(held[self.free])
        return -(self.k_rx @ u).T

    def capacitance(
        self, grounded: np.ndarray | None = None, nodes: np.ndarray | None = None
    ) -> float:
        """The centre crossing's Tx-Rx mutual capacitance (fF) (`crossings`)."""
        return float(self.crossings(grounded, nodes)[self.centre])

    def object_nodes(self, name: str, dx: float, dy: float, gap: float) -> np.ndarray:
        """Air nodes inside object `name` with its tip at (dx, dy, gap)."""
        return np.flatnonzero(self.objects[name].contains(self.mesh.nodes, dx, dy, gap) & self.air)

    def with_object(self, name: str, dx: float, dy: float, gap: float) -> float:
        return self.capacitance(self.object_nodes(name, dx, dy, gap))


def _volumes(nodes: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes (times 6) of tets (t, 4)."""
    x = nodes[tets]
    return np.einsum("ti,ti->t", x[:, 1] - x[:, 0], np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]))


def _yarn_order(name: str) -> tuple[str, int]:
    kind, _, k = name.partition("+") if "+" in name else name.partition("-")
    return (kind, int(k) * (1 if "+" in name else -1) if k else 0)


def touch_table(
    solver: CellSolver,
    spec: CellSpec,
    objects: Sequence[str],
    gaps: np.ndarray,
    c0: np.ndarray,
    progress: Callable[[str], None] | None = None,
    steps: int | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(dx (x,), dy (y,), dC (k, g, x, y) fF, mismatch fF) over the table's offsets.

    The object visits `positions_mm` (`steps` across half a pitch) of the quarter
    cell; each solve gives every crossing's C, and the crossing i pitches, j pitches
    from the centre sees the object at the offset (X - i px, Y - j py). The cell is
    symmetric in x and in y, so the table holds |offset| and is mirrored. Offsets two
    crossings see (the quarter cell's edges) are averaged; `mismatch` is the largest
    difference between them (the cell's departure from translation invariance)."""
    px, py = spec.pitch_x_mm, spec.pitch_y_mm
    xs, ys = positions_mm(px, steps), positions_mm(py, steps)
    dx, dy = offsets_mm(px, steps), offsets_mm(py, steps)
    ax, ay = dx[dx >= 0], dy[dy >= 0]
    ks_x = np.array([_yarn_order(n)[1] for n in solver.tx_names])
    ks_y = np.array([_yarn_order(n)[1] for n in solver.rx_names])
    step_x, step_y = ax[1] - ax[0], ay[1] - ay[0]
    total = np.zeros((len(objects), len(gaps), len(ax), len(ay)))
    count = np.zeros_like(total)
    first = np.full_like(total, np.nan)
    mismatch = 0.0
    for k, name in enumerate(objects):
        for g, gap in enumerate(gaps):
            for x in xs:
                for y in ys:
                    d = solver.object_crossings(name, x, y, gap) - c0
                    for i, kx in enumerate(ks_x):
                        ix = round(abs(x - kx * px) / step_x)
                        if ix >= len(ax):
                            continue
                        for j, ky in enumerate(ks_y):
                            iy = round(abs(y - ky * py) / step_y)
                            if iy >= len(ay):
                                continue
                            at = (k, g, ix, iy)
                            if count[at]:
                                mismatch = max(mismatch, abs(d[i, j] - first[at]))
                            else:
                                first[at] = d[i, j]
                            total[at] += d[i, j]
                            count[at] += 1
            if progress is not None:
                progress(f"{name}: gap {gap:g} mm done")
    if not count.all():
        raise SolverError("crossing cell: the crossings do not cover the table's offsets")
    quarter = total / count
    src_x = np.round(np.abs(dx) / step_x).astype(int)
    src_y = np.round(np.abs(dy) / step_y).astype(int)
    return dx, dy, quarter[:, :, src_x][:, :, :, src_y], float(mismatch)


def glue_radius_mm(spec: CellSpec) -> float:
    """The glued crossing's radius about its vertical axis (mm): two yarn radii and the
    insulation (an assumption: the paper gives no size for its glue)."""
    return 2 * spec.yarn_radius_mm + spec.insulation_mm


def deformation_table(
    solver: CellSolver,
    spec: CellSpec,
    c0: float,
    glued: bool = True,
    glue_mm: float | None = None,
    neutral_mm: float = NEUTRAL_MM,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(c_stretch (2, s), c_bend (2, c)) fF, strain and curvature lists with 0 first.
    Glued (the paper's crossing, the default): nothing within `glue_mm` (default
    `glue_radius_mm`) of the crossing's axis moves, the deformation ramps in over half a
    pitch beyond; not glued: every node moves with the silicone (the yarns too). Bent
    about a neutral plane `neutral_mm` under the surface."""
    nodes = solver.mesh.nodes
    glue = glue_radius_mm(spec) if glue_mm is None else glue_mm
    ramp = min(spec.pitch_x_mm, spec.pitch_y_mm) / 2

    def move(target: np.ndarray) -> np.ndarray:
        return deform.deformed(nodes, target, glue, ramp) if glued else target

    strains = np.array([0.0, *STRAINS])
    curvatures = np.array([0.0, *CURVATURES_PER_MM])
    c_stretch = np.full((2, len(strains)), c0)
    c_bend = np.full((2, len(curvatures)), c0)
    for a, axis in enumerate(("x", "y")):
        for i, s in enumerate(strains[1:], 1):
            c_stretch[a, i] = solver.capacitance(nodes=move(deform.stretched(nodes, axis, s)))
        for i, kappa in enumerate(curvatures[1:], 1):
            moved = move(deform.bent(nodes, axis, kappa, neutral_mm))
            c_bend[a, i] = solver.capacitance(nodes=moved)
    solver.capacitance(nodes=nodes)  # back to the cell at rest
    return strains, c_stretch, curvatures, c_bend


def compute(
    spec: CellSpec,
    permittivity: float,
    gaps_mm: Sequence[float] | np.ndarray,
    objects: Iterable[str] = tuple(OBJECTS),
    order: int = 1,
    time_limit_s: float = 120.0,
    progress: Callable[[str], None] | None = None,
) -> CrossingTable:
    """The crossing's table for a cell (`cell_spec`); gmsh is killed after time_limit_s.

    The touches are solved on `spec`'s cell of 3 x 3 crossings (`touch_table`), the
    deformations on the one-crossing cell of the same design (`deformation_spec`): its
    nodes are moved, and the wide cell bent as the paper's pad would fold over itself.
    The deformation's C_delta - C0 is of that cell, added to the wide cell's C0."""
    from fruitcli.electrostatics.cell_mesh import mesh_cell

    t0 = time.perf_counter()
    mesh = mesh_cell(spec, order, time_limit_s)
    small = deformation_spec(spec)
    mesh_def = mesh_cell(small, order, time_limit_s)
    t_mesh = time.perf_counter() - t0
    if progress is not None:
        progress(f"cell meshed: {len(mesh.tets)} tets, {len(mesh.nodes)} nodes")
    t1 = time.perf_counter()
    solver = CellSolver(mesh, permittivity)
    c0_all = solver.crossings()
    c0 = float(c0_all[solver.centre])
    gaps = np.asarray(gaps_mm, float)
    dx, dy, dc, mismatch = touch_table(solver, spec, list(objects), gaps, c0_all, progress)
    def_solver = CellSolver(mesh_def, permittivity)
    c0_def = def_solver.capacitance()
    strains, c_stretch, curvatures, c_bend = deformation_table(def_solver, small, c0_def)
    c_stretch += c0 - c0_def
    c_bend += c0 - c0_def
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
        {
            "tets": int(len(mesh.tets)),
            "nodes": int(len(mesh.nodes)),
            "order": order,
            "reach_pitches": spec.reach,
            "c0_spread_ff": float(np.ptp(c0_all)),
            "offset_mismatch_ff": mismatch,
        },
    )
