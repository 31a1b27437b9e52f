"""The hyperelastic model of one body on any element family (`fruitcli.fem.elements`)
with any material of `fruitcli.fem.materials`: the same loads as the paper's
corotational `Model` (chamber pressure or volume as a Lagrange multiplier per chamber,
follower pressure on curved walls, jig springs, gravity, fixed and moved regions) and
the same interface to the solver (`fem_model.FemModel`), so both are solved alike.

    from fruitcli.fem.continuum import ContinuumModel
    model = ContinuumModel.from_arrays(nodes2, tets10, material("neo-hookean", 100, 0.49),
                                       "p2", chambers={"c": tris6}, fixed_nodes=idx)

Units: mm, kPa, mN (see `fruitcli.fem.units`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from fruitcli.errors import MeshError, SceneError
from fruitcli.fem.corotational_model import Model, pin_rigid_modes, prescribed_dofs
from fruitcli.fem.element_sums import node_incidence
from fruitcli.fem.elements import integrate, tet4
from fruitcli.fem.elements.integrate import evaluate
from fruitcli.fem.elements.lagrange import ELEMENTS, Family, tet_shape, tet_shape_gradients
from fruitcli.fem.loads.cavity import Wall
from fruitcli.fem.loads.springs import Jig
from fruitcli.fem.materials.build import Material
from fruitcli.fem.solver.assemble import CsrPattern, scatter
from fruitcli.fem.tolerances import SLIVER_QUALITY
from fruitcli.fem.units import body_force_mn_mm3

if TYPE_CHECKING:
    from collections.abc import Iterator

    from numpy.typing import ArrayLike

    from fruitcli.fem.solver.continuum_linsolve import ContinuumSolver


def reference_gradients(
    nodes: np.ndarray, conn: np.ndarray, fam: Family
) -> tuple[np.ndarray, np.ndarray]:
    """(dN (m, q, nen, 3) 1/mm, weights (m, q) mm^3) at the family's volume rule; raises
    MeshError naming an element whose map from the reference tet is not invertible."""
    pts, w = fam.volume_rule()
    dref = tet_shape_gradients(pts, fam.order)  # (q, nen, 3)
    x = nodes[conn]  # (m, nen, 3)
    jac = np.einsum("mai,qaj->mqij", x, dref)  # dX/dxi
    det = np.linalg.det(jac)
    bad = np.flatnonzero(~(det > 0).all(axis=1))
    if len(bad):
        c = x[bad[0], :4].mean(axis=0)
        raise MeshError(
            f"mesh: element {bad[0]} at ({c[0]:.2f}, {c[1]:.2f}, {c[2]:.2f}) mm "
            "is inverted or too curved for its edge nodes; remesh finer"
        )
    inv = np.linalg.inv(jac)
    dn = np.einsum("qaj,mqji->mqai", dref, inv)
    return np.ascontiguousarray(dn), np.ascontiguousarray(det * w)


def loop_order(rest: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """(m,) the elements sorted by their centroid's x (mm; stable): the order of the
    element loop, so that consecutive elements share nodes and the scatter of their
    tangent blocks adds into nearby entries of the sparse matrix (on the quadratic
    default Fruit 10-13 ms of CPU instead of 16-19 ms in the mesh's order)."""
    return np.argsort(rest[conn[:, :4]].mean(axis=1)[:, 0], kind="stable")


def support_check(rest: np.ndarray, held: np.ndarray, what: str) -> None:
    """Refuse a support whose nodes lie on one line (rotations about it stay free)."""
    pts = rest[held]
    size = float(np.ptp(rest, axis=0).max())
    if len(pts) < 3 or np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)[1] <= 1e-6 * size:
        raise SceneError(
            f"{what} holds the body at {len(pts)} node(s) on one line or "
            "point, so it can still rotate about it: widen the region "
            "(a face or a volume of the body)"
        )


DILATATION_STEP = 1.0
"""`ContinuumModel.dilatation_step` in shear moduli of pressure. A Newton step along
straight lines turns elements by a linearized rotation, which dilates them by about
the square of the angle (7 % at 15 degrees); a nearly incompressible body (nu = 0.49:
kappa = 50 mu) answers with a spurious pressure of several mu, whose geometric
stiffness makes the tangent indefinite, and Newton then wanders (the touchpad's jig
step of 15 degrees from rest: corrections of 10-60 mm at a relative residual of 2e-3,
over 8 min). Limited to mu of pressure per step, the first steps turn the body a few
degrees at a time and Newton converges."""


FIRST_BULK_RATIO = 50.0
"""A state of a body stiffer in bulk than this many shear moduli (nu above about 0.495)
is solved from rest first with this bulk modulus (nu about 0.49), then with bulk moduli
BULK_STAGE_FACTOR times larger in turn, each from the last equilibrium, until its own
(`ContinuumModel.bulk_stages`). Newton converges only within about mu / kappa of the
solution: a step along straight lines turns elements and dilates them by the square of
the angle, which the bulk modulus answers with spurious pressure. On the default Fruit
at nu = 0.4999 under gravity (its overhang bends 20 mm) the state solved directly took
over 240 s (Newton 22 steps per quarter of the load, relative residual near 1 for
15 of them; the load path's secant start then dilated elements by 6 %); through
nu = 0.49 and 0.499, 17 Newton steps (12, 3, 2) and 14 s, to the same equilibrium
(largest displacement 20.274 mm both ways)."""

BULK_STAGE_FACTOR = 10.0
"""Growth of the bulk modulus from one continuation stage to the next (see
FIRST_BULK_RATIO): each stage starts within a few Newton steps of its equilibrium."""


@dataclass
class ContinuumModel:
    """A body ready to solve. Build it with `ContinuumModel.from_arrays`."""

    escalate_on_damping = False
    """Newton keeps the full tangent after a damped step (it stays a descent direction
    for this energy; the clamped tangent would slow convergence to linear)."""

    secant_while_rotating = False
    """Load steps that turn a jig start from the last converged step, not from the
    secant through the two before it: the secant extrapolates a rotation along straight
    lines, which a nearly incompressible body resists with its bulk modulus, while
    Newton's first iteration from the last step (the tangent predictor) keeps its
    volume. On the default Fruit's jig state (nu = 0.49) the secant start inverted
    elements and Newton crawled (over 8 min); without it, 4 iterations per step."""

    rest: np.ndarray  # (n, 3) mm, corners first then edge nodes
    conn: np.ndarray  # (m, nen)
    family: Family
    material: Material
    dn: np.ndarray
    wq: np.ndarray
    volumes_mm3: np.ndarray
    chamber_names: list[str]
    chamber_tris: list[np.ndarray]
    chamber_rest_volume_mm3: np.ndarray
    body_force_mn: np.ndarray
    jigs: list[Jig]
    fixed_nodes: np.ndarray
    pinned_dofs: np.ndarray
    pattern: CsrPattern
    spring_diag: np.ndarray
    notes: list[str]
    prescribed_dofs: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    prescribed_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def n_nodes(self) -> int:
        return len(self.rest)

    @property
    def tets(self) -> np.ndarray:
        """(m, 4) corner nodes of each element."""
        return self.conn[:, :4]

    @property
    def elements(self) -> np.ndarray:
        """(m, nodes per tet) nodes of each element."""
        return self.conn

    @property
    def element_name(self) -> str:
        return self.family.name

    @property
    def material_name(self) -> str:
        return self.material.model

    @property
    def young_modulus_kpa(self) -> float:
        return self.material.young_modulus_kpa

    @property
    def poisson_ratio(self) -> float:
        return self.material.poisson_ratio

    @classmethod
    def from_arrays(
        cls,
        nodes: ArrayLike,
        conn: ArrayLike,
        mat: Material,
        element: str = "p2",
        *,
        density_kg_m3: float = 0.0,
        gravity_m_s2: ArrayLike | None = None,
        fixed_nodes: ArrayLike | None = None,
        chambers: dict | None = None,
        jigs: list[Jig] | None = None,
        prescribed: list | None = None,
        min_quality: float = SLIVER_QUALITY,
    ) -> ContinuumModel:
        """Validate and precompute. nodes (n, 3) mm, conn (m, nen) of `element`'s
        family, chambers {name: (t, 3 or 6) wall triangles, normals out of the cavity},
        prescribed [(node indices, (3,) displacement mm[, (3,) components held])]
        (moved clamps, rollers; `fruitcli.fem.corotational_model.prescribed_dofs`)."""
        fam = ELEMENTS[element]
        rest, conn = _checked_elements(nodes, conn, fam, element, min_quality)
        dn, wq = reference_gradients(rest, conn, fam)
        n = len(rest)
        names, tris_list, walls, v_rest = _chamber_walls(rest, chambers, fam)
        body = _body_force(fam, conn, wq, n, density_kg_m3, gravity_m_s2)
        fixed = np.unique(np.asarray([] if fixed_nodes is None else fixed_nodes, np.int64))
        p_dofs, p_mm = prescribed_dofs(prescribed)
        jigs = list(jigs or [])
        pinned, notes = _supports(rest, conn, fixed, p_dofs, jigs, bool(np.any(body)))
        free_mask = np.ones(3 * n, bool)
        free_mask[(3 * fixed[:, None] + np.arange(3)).ravel()] = False
        free_mask[p_dofs] = False
        free_mask[pinned] = False
        pattern = CsrPattern.build(conn[loop_order(rest, conn)], n, free_mask)
        spring = np.zeros(3 * n)
        for jig in jigs:
            np.add.at(
                spring, (3 * jig.nodes[:, None] + np.arange(3)).ravel(), jig.stiffness_mn_per_mm
            )
        model = cls(
            rest=rest,
            conn=conn,
            family=fam,
            material=mat,
            dn=dn,
            wq=wq,
            volumes_mm3=wq.sum(axis=1),
            chamber_names=names,
            chamber_tris=tris_list,
            chamber_rest_volume_mm3=v_rest,
            body_force_mn=body,
            jigs=jigs,
            fixed_nodes=fixed,
            pinned_dofs=pinned,
            pattern=pattern,
            spring_diag=spring[pattern.free],
            notes=notes,
            prescribed_dofs=p_dofs,
            prescribed_mm=p_mm,
        )
        model.__dict__["_walls"] = walls
        model.evaluate(rest, tangent=False)  # compiled now, not inside the first state
        return model

    # -- physics at a configuration x (n, 3) -------------------------------------------

    def evaluate(
        self, x: np.ndarray, tangent: bool = False, *, reuse: bool = False
    ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray | None]:
        """(internal forces (n, 3) mN, strain energy mN mm or nan when an element is
        inverted, smallest det F per element (m,), element tangents (m, d, d) or None;
        the tangents in `loop_order`, as `pattern` assembles them). With `reuse` the
        tangents are written over the model's own array (`_blocks`), valid until the
        next such call; otherwise into a new one."""
        x = np.ascontiguousarray(x, dtype=float)
        forces = np.zeros((self.n_nodes, 3))
        d = 3 * self.conn.shape[1]
        if not tangent:
            blocks = np.empty((0, d, d))
        elif reuse:
            blocks = self._blocks
        else:
            blocks = np.empty((len(self.conn), d, d))
        jmin = np.empty(len(self.conn))
        order, conn, dn, wq, incidence = self._loop
        energy = evaluate(
            x,
            conn,
            dn,
            wq,
            self.material.constants(),
            self.family.mean_dilatation,
            tangent,
            forces,
            blocks,
            jmin,
            *incidence,
        )
        if energy == -1.0:
            energy = np.nan
        det_f = np.empty_like(jmin)
        det_f[order] = jmin
        return forces, energy, det_f, (blocks if tangent else None)

    extent_mm = Model.extent_mm  # the same cached rest extent (mm)

    @functools.cached_property
    def _blocks(self) -> np.ndarray:
        """(m, d, d) the array Newton's element tangents are written over, one tangent
        after another (`kinematics`, `tangent`): on the default Fruit 64 MB, a tangent 64
        ms of CPU instead of 71 with a new array (its page faults) every time. The
        element loop writes every entry, an inverted element's block as zeros."""
        d = 3 * self.conn.shape[1]
        return np.empty((len(self.conn), d, d))

    @functools.cached_property
    def _loop(self):
        """(order, conn, dn, wq, node incidence) of the element loop: the elements in
        `loop_order`, the order of the tangent blocks `evaluate` returns and `pattern`
        assembles."""
        order = loop_order(self.rest, self.conn)
        conn = np.ascontiguousarray(self.conn[order])
        dn, wq = np.ascontiguousarray(self.dn[order]), np.ascontiguousarray(self.wq[order])
        return order, conn, dn, wq, node_incidence(conn, self.n_nodes)

    def kinematics(
        self, x: np.ndarray, tangent: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(state, state, smallest det F per element): the state is x itself, evaluated
        once here and reused by `forces_and_energy` (Newton's interface); with `tangent`
        the element tangents too, kept for `tangent` at this state (one element loop
        instead of two when Newton knows it will need the tangent here)."""
        x = np.array(x, float)
        forces, energy, jmin, blocks = self.evaluate(x, tangent=tangent, reuse=True)
        self.__dict__["_last"] = (x, forces, energy, blocks)
        return x, x, jmin

    def forces_and_energy(
        self, f: np.ndarray, rot: np.ndarray | None = None
    ) -> tuple[np.ndarray, float]:
        """Internal forces (n, 3) mN and strain energy (mN mm) at the state of
        `kinematics`."""
        last = self.__dict__.get("_last")
        if last is None or last[0] is not f:
            forces, energy, _, _ = self.evaluate(f)
            return forces, energy
        return last[1], last[2]

    def tangent(self, x: np.ndarray, project: bool = False) -> sp.csr_matrix:
        """Material and geometric tangent over the free dofs (mN/mm) plus the springs;
        with `project`, each element's block clamped to positive semi-definite."""
        last = self.__dict__.get("_last")
        if last is not None and last[0] is x and last[3] is not None:
            blocks = last[3]  # evaluated with the forces by `kinematics(x, tangent=True)`
        else:
            _, _, _, blocks = self.evaluate(x, tangent=True, reuse=True)
            if last is not None and last[3] is blocks:  # written over: no longer last's
                self.__dict__["_last"] = (*last[:3], None)
        if project:
            w, v = np.linalg.eigh(blocks)
            blocks = np.einsum("mij,mj,mkj->mik", v, np.maximum(w, 0.0), v)
        return self.pattern.assemble(blocks, self.spring_diag)

    @property
    def walls(self) -> list[Wall]:
        return self.__dict__["_walls"]

    def chamber_volumes(self, x: np.ndarray) -> np.ndarray:
        """(K,) cavity volumes (mm^3) at x."""
        return np.array([w.volume(x) for w in self.walls])

    def chamber_gradients(self, x: np.ndarray) -> np.ndarray:
        """(K, n, 3) dV/dx per chamber (mm^2)."""
        if not self.walls:
            return np.zeros((0, len(x), 3))
        return np.stack([w.gradient(x) for w in self.walls])

    def load_stiffness(self, x: np.ndarray, pressure_kpa: np.ndarray) -> sp.csr_matrix | None:
        """Sparse (n_free, n_free) stiffness of the follower pressure, -sum_k p_k
        d2V_k/dx2 (mN/mm), or None without chamber pressure."""
        if not self.walls or not np.any(pressure_kpa):
            return None
        slots = self._wall_slots
        if slots is None:  # a wall pair in no element: the general sparse sum
            free = self.pattern.free
            h = sum(
                -pk * w.hessian(x, self.n_nodes)
                for pk, w in zip(pressure_kpa, self.walls, strict=True)
                if pk
            )
            return sp.csr_matrix(h)[free][:, free]
        # the walls' entries added into the tangent's own pattern (`add_in_pattern`)
        pairs = [
            (kept, slot, -pk * w.hessian(x, self.n_nodes).data[kept])
            for pk, w, (kept, slot) in zip(pressure_kpa, self.walls, slots, strict=True)
            if pk
        ]
        pat = self.pattern
        data = scatter(
            np.concatenate([v for _, _, v in pairs]),
            np.concatenate([slot for _, slot, _ in pairs]),
            pat.nnz,
        )
        n = len(pat.free)
        return sp.csr_matrix((data, pat.indices, pat.indptr), shape=(n, n))

    @functools.cached_property
    def _wall_slots(self) -> list[tuple[np.ndarray, np.ndarray]] | None:
        """Per wall, (entries of its Hessian's COO data between free dofs, their slots in
        the CSR data of `pattern`); None when some pair of a wall's nodes shares no
        element (then the pattern has no slot for it)."""
        pat = self.pattern
        n = len(pat.free)
        new = np.full(3 * self.n_nodes, -1, np.int64)
        new[pat.free] = np.arange(n)
        keys = np.repeat(np.arange(n, dtype=np.int64), np.diff(pat.indptr)) * n + pat.indices
        out = []
        for w in self.walls:
            h = w.hessian(self.rest, self.n_nodes)
            i, j = new[h.row], new[h.col]
            kept = np.flatnonzero((i >= 0) & (j >= 0))
            want = i[kept] * n + j[kept]
            slot = np.minimum(np.searchsorted(keys, want), len(keys) - 1)
            if not np.array_equal(keys[slot], want):
                return None
            out.append((kept, slot.astype(pat.entry_slot.dtype)))
        return out

    # the loads are written once, on the paper's model: they only use the rest
    # positions, body force, jigs and the chamber volumes and gradients above
    external_forces = Model.external_forces
    external_potential = Model.external_potential

    def mean_dilatation(self, x: np.ndarray) -> np.ndarray:
        """(m,) volume ratio of each element, det F averaged over its volume."""
        return integrate.mean_dilatation(
            np.ascontiguousarray(x, dtype=float), self.conn, self.dn, self.wq, self.volumes_mm3
        )

    @property
    def dilatation_step(self) -> float:
        """How much further from 1 an element's volume ratio may go in one Newton step
        (the line search shortens longer steps; steps towards 1 are free):
        DILATATION_STEP mu / kappa, a pressure change of DILATATION_STEP shear moduli
        (0.02 at nu = 0.49)."""
        m = self.material
        return DILATATION_STEP * m.shear_modulus_kpa / m.bulk_modulus_kpa

    def bulk_stages(self) -> list[float]:
        """Bulk moduli (kPa) a state solved from rest passes through before this model's
        own: FIRST_BULK_RATIO mu times BULK_STAGE_FACTOR^i while below half the bulk
        modulus (none for a body less stiff in bulk; see FIRST_BULK_RATIO)."""
        mu, kappa = self.material.shear_modulus_kpa, self.material.bulk_modulus_kpa
        stages = [FIRST_BULK_RATIO * mu]
        while stages[-1] < 0.5 * kappa:
            stages.append(stages[-1] * BULK_STAGE_FACTOR)
        return stages[:-1]

    @contextlib.contextmanager
    def bulk_modulus(self, kappa_kpa: float) -> Iterator[ContinuumModel]:
        """The model with its material's bulk modulus set to kappa_kpa (kPa) inside the
        `with` block (restored after it)."""
        saved = self.material
        self.material = dataclasses.replace(saved, bulk_modulus_kpa=float(kappa_kpa))
        self.__dict__.pop("_last", None)
        try:
            yield self
        finally:
            self.material = saved
            self.__dict__.pop("_last", None)

    def min_det_f(self, x: np.ndarray) -> np.ndarray:
        return self.evaluate(x)[2]

    def worst_element(self, det_f: np.ndarray) -> str:
        i = int(np.argmin(det_f))
        c = self.rest[self.conn[i, :4]].mean(axis=0)
        return f"element {i} at ({c[0]:.1f}, {c[1]:.1f}, {c[2]:.1f}) mm (det F = {det_f[i]:.3g})"

    def make_solver(self, method: str = "pcg") -> ContinuumSolver:
        from fruitcli.fem.solver.continuum_linsolve import ContinuumSolver

        return ContinuumSolver(self, method)

    def map_points(self, tet_index: np.ndarray, bary: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Positions (t, 3), or (s, t, 3) for x (s, n, 3), of points given by their
        element and barycentric (reference) coordinates (t, 4), with the element's own
        shape functions (quadratic on 10-node tets)."""
        shape = tet_shape(bary, self.family.order)  # (t, nen)
        return np.einsum("...tai,ta->...ti", x[..., self.conn[tet_index], :], shape)


def _checked_elements(
    nodes: ArrayLike, conn: ArrayLike, fam: Family, element: str, min_quality: float
) -> tuple[np.ndarray, np.ndarray]:
    """(nodes (n, 3) mm, conn (m, nen)) as contiguous arrays, or MeshError in one line:
    conn not (m, nen) of `element`'s family, a node index out of range, a sliver (tet
    quality below min_quality) or a negatively oriented tet."""
    rest = np.ascontiguousarray(nodes, dtype=float)
    conn = np.ascontiguousarray(conn, dtype=np.int64)
    if conn.ndim != 2 or conn.shape[1] != fam.nodes_per_tet or len(conn) == 0:
        raise MeshError(
            f"elements: expected a non-empty (M, {fam.nodes_per_tet}) array for element {element!r}"
        )
    if conn.min() < 0 or conn.max() >= len(rest):
        raise MeshError("elements: node index out of range")
    corners = conn[:, :4]
    tet4.refuse_slivers(rest, corners, min_quality)
    if (tet4.signed_volumes(rest, corners) < 0).any():
        raise MeshError("elements: expected positively oriented tets")
    return rest, conn


def _chamber_walls(
    rest: np.ndarray, chambers: dict | None, fam: Family
) -> tuple[list[str], list[np.ndarray], list[Wall], np.ndarray]:
    """(names, wall triangles (t, 3 or 6), walls, rest volumes (K,) mm^3) of the chambers
    {name: triangles, normals out of the cavity}; MeshError in one line for a wall that
    is not (t, nodes per triangle) with t >= 4, or one whose normals point in."""
    names, tris_list, walls = [], [], []
    for name, tris in (chambers or {}).items():
        tris = np.asarray(tris, np.int64)
        if tris.ndim != 2 or tris.shape[1] != fam.nodes_per_tri or len(tris) < 4:
            raise MeshError(
                f"chamber {name}: expected a closed wall of (T, {fam.nodes_per_tri}) triangles"
            )
        names.append(str(name))
        tris_list.append(tris)
        walls.append(Wall(tris))
    v_rest = np.array([w.volume(rest) for w in walls])
    if (v_rest <= 0).any():
        raise MeshError(
            f"chamber {names[int(np.argmin(v_rest))]}: wall normals must point out of the cavity"
        )
    return names, tris_list, walls, v_rest


def _body_force(
    fam: Family,
    conn: np.ndarray,
    wq: np.ndarray,
    n: int,
    density_kg_m3: float,
    gravity_m_s2: ArrayLike | None,
) -> np.ndarray:
    """(n, 3) nodal gravity force (mN) at full load: the consistent load int N_a dV
    (mm^3, from the quadrature weights wq (m, q)) times the body force density; zero
    without gravity or density."""
    body = np.zeros((n, 3))
    if gravity_m_s2 is not None and density_kg_m3 > 0:
        pts, w = fam.volume_rule()
        shape = tet_shape(pts, fam.order)  # (q, nen)
        per = np.einsum("mq,qa->ma", wq, shape)  # (m, nen) mm^3: int N_a dV
        np.add.at(
            body,
            conn.ravel(),
            per.reshape(-1, 1) * body_force_mn_mm3(density_kg_m3, gravity_m_s2),
        )
    return body


def _supports(
    rest: np.ndarray,
    conn: np.ndarray,
    fixed: np.ndarray,
    p_dofs: np.ndarray,
    jigs: list[Jig],
    gravity_on: bool,
) -> tuple[np.ndarray, list[str]]:
    """(dofs pinned against the rigid modes, notes): a body held by nothing (no fixed
    node, moved region or jig) gets a 3-2-1 support and a note saying so, or, under
    gravity, SceneError in one line; a body held only by fixed nodes or only by jigs
    must hold all six rigid modes (`support_check`); rollers (prescribed dofs with
    components free) are trusted to."""
    held = np.unique(np.concatenate([fixed, p_dofs // 3]))
    notes: list[str] = []
    pinned = np.zeros(0, np.int64)
    if len(held) == 0 and not jigs:
        if gravity_on:
            raise SceneError(
                "[gravity]: nothing supports the body, so gravity has no "
                "equilibrium; add a [[fixed]] region or a [[jig]], or "
                "remove [gravity]"
            )
        pinned = pin_rigid_modes(rest[: int(conn[:, :4].max()) + 1])
        notes.append(
            "no fixed region and no jig: the six rigid modes are removed by a "
            f"3-2-1 support at nodes {sorted(set((pinned // 3).tolist()))} "
            "(the loads are self-equilibrated)"
        )
    elif not jigs and len(p_dofs) < 3 * len(np.unique(p_dofs // 3)):
        pass  # rollers: the caller's components hold the rigid modes
    elif not jigs:
        support_check(rest, held, "[[fixed]]")
    elif len(held) == 0:
        support_check(rest, np.unique(np.concatenate([j.nodes for j in jigs])), "[[jig]]")
    return pinned, notes
