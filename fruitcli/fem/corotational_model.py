"""The mechanical model of one body: rest mesh, Hooke material, fixed nodes, chambers,
jig springs and gravity, with everything that does not change precomputed.

Lower-level API (no files), for studies that sweep E, nu, pressure, jig stiffness,
mesh size, tolerance or linear solver::

    from fruitcli.fem.corotational_model import Model
    from fruitcli.fem.state_load import Load
    from fruitcli.fem.solver.options import SolverOptions
    from fruitcli.fem.solver.state import solve_state
    model = Model.from_arrays(nodes, tets, E_kpa=100.0, nu=0.45,
                              fixed_nodes=idx, chambers={"c0": tris})
    res = solve_state(model, Load.pressures([5.0]), options=SolverOptions(tolerance=1e-6))
    res.displacement_mm, res.iterations, res.residual, res.subdivisions, res.min_det_f

Units: mm, kPa, mN (see `fruitcli.fem.units`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import MeshError, SceneError, SolverError
from fruitcli.fem.element_sums import node_incidence
from fruitcli.fem.elements import tet4
from fruitcli.fem.loads import pressure
from fruitcli.fem.loads.springs import Jig
from fruitcli.fem.materials import corotation
from fruitcli.fem.materials import corotation_kernels as kernels
from fruitcli.fem.solver.assemble import CsrPattern
from fruitcli.fem.state_load import Load
from fruitcli.fem.tolerances import SLIVER_QUALITY
from fruitcli.fem.units import body_force_mn_mm3

if TYPE_CHECKING:
    import scipy.sparse as sp
    from numpy.typing import ArrayLike

    from fruitcli.fem.solver.linsolve import TangentSolver


def pin_rigid_modes(rest: np.ndarray) -> np.ndarray:
    """(6,) global dofs of a statically determinate 3-2-1 support: node a (x, y, z),
    node b far along x (y, z), node c far from line ab in the xy plane (z). It removes
    the six rigid modes without loading a self-equilibrated body."""
    a = int(np.argmin(rest[:, 0]))
    b = int(np.argmax(rest[:, 0]))
    d = rest - rest[a]
    db = d[b]
    c = int(np.argmax(np.abs(db[0] * d[:, 1] - db[1] * d[:, 0])))
    return np.array([3 * a, 3 * a + 1, 3 * a + 2, 3 * b + 1, 3 * b + 2, 3 * c + 2])


def prescribed_dofs(prescribed: list | None) -> tuple[np.ndarray, np.ndarray]:
    """(global dofs (d,), their displacement at full load (d,) mm) of prescribed
    [(node indices, (3,) displacement mm[, (3,) components held])]: a moved clamp
    holds all three components; a mask holds some (a roller)."""
    dofs, vals = [np.zeros(0, np.int64)], [np.zeros(0)]
    for entry in prescribed or []:
        nodes, disp = np.asarray(entry[0], np.int64), np.asarray(entry[1], float)
        mask = np.asarray(entry[2], bool) if len(entry) > 2 else np.ones(3, bool)
        comp = np.flatnonzero(mask)
        dofs.append((3 * nodes[:, None] + comp).ravel())
        vals.append(np.tile(disp[comp], len(nodes)))
    d, v = np.concatenate(dofs), np.concatenate(vals)
    d, first = np.unique(d, return_index=True)
    return d, v[first]


@dataclass
class Model:
    """A body ready to solve (a `fem_model.FemModel`): the paper's corotational Hooke
    model on linear tets. Build it with `Model.from_arrays`."""

    element_name = "p1"
    material_name = "corotational"
    escalate_on_damping = True
    """Newton takes the next, safer tangent after a damped step."""
    secant_while_rotating = True
    dilatation_step = 0.0
    """No limit on an element's volume change per Newton step."""

    rest: np.ndarray
    tets: np.ndarray
    young_modulus_kpa: float
    poisson_ratio: float
    dm_inv: np.ndarray
    volumes_mm3: np.ndarray
    k0: np.ndarray
    chamber_names: list[str]
    chamber_tris: list[np.ndarray]
    chamber_rest_volume_mm3: np.ndarray
    body_force_mn: np.ndarray  # (n, 3) nodal gravity force at full load
    jigs: list[Jig]
    fixed_nodes: np.ndarray
    pinned_dofs: np.ndarray
    pattern: CsrPattern
    spring_diag: np.ndarray  # (n_free,) mN/mm
    notes: list[str]
    prescribed_dofs: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    prescribed_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def n_nodes(self) -> int:
        return len(self.rest)

    @property
    def elements(self) -> np.ndarray:
        """(m, 4) nodes of each element: the linear tets."""
        return self.tets

    def bulk_stages(self) -> list[float]:
        """None: the corotational model is solved at its own bulk modulus from rest."""
        return []

    @classmethod
    def from_arrays(
        cls,
        nodes: ArrayLike,
        tets: ArrayLike,
        E_kpa: float,
        nu: float,
        *,
        density_kg_m3: float = 0.0,
        gravity_m_s2: ArrayLike | None = None,
        fixed_nodes: ArrayLike | None = None,
        chambers: dict | None = None,
        jigs: list[Jig] | None = None,
        prescribed: list | None = None,
        min_quality: float = SLIVER_QUALITY,
    ) -> Model:
        """Validate and precompute. nodes (n, 3) mm, tets (m, 4), E (kPa), nu, chambers
        {name: (t, 3) triangles}, fixed_nodes indices, jigs with node indices,
        prescribed [(node indices, (3,) displacement mm)] (moved clamps)."""
        rest, tets, vol = _checked_mesh(nodes, tets, E_kpa, nu, min_quality)
        vol = np.abs(vol)
        lam, mu = tet4.lame_parameters(E_kpa, nu)
        grads = tet4.shape_gradients(rest, tets)
        k0 = tet4.element_stiffness(grads, vol, lam, mu)
        dm_inv = np.linalg.inv(tet4.edge_matrices(rest, tets))
        n = len(rest)
        notes = []
        if nu > 0.49:
            notes.append(
                f"nu = {nu} is close to 0.5: linear tets lock (too stiff in bending "
                "and under pressure)"
            )

        names, tris_list = _chamber_surfaces(rest, chambers)
        v_rest = np.array([pressure.cavity_volume(rest, t) for t in tris_list])

        body = np.zeros((n, 3))
        if gravity_m_s2 is not None and density_kg_m3 > 0:
            per_tet = vol[:, None] * body_force_mn_mm3(density_kg_m3, gravity_m_s2) / 4.0
            body = corotation.scatter_nodes(tets, np.repeat(per_tet[:, None], 4, axis=1), n)

        p_dofs, p_mm = prescribed_dofs(prescribed)
        fixed = np.unique(np.asarray([] if fixed_nodes is None else fixed_nodes, np.int64))
        jigs = list(jigs or [])
        pinned = np.zeros(0, np.int64)
        if len(fixed) == 0 and not jigs and not len(p_dofs):
            if gravity_m_s2 is not None and density_kg_m3 > 0 and np.any(gravity_m_s2):
                raise SceneError(
                    "[gravity]: nothing supports the body, so gravity has no "
                    "equilibrium; add a [[fixed]] region or a [[jig]], or "
                    "remove [gravity]"
                )
            pinned = pin_rigid_modes(rest)
            notes.append(
                "no fixed region and no jig: the six rigid modes are removed by a "
                f"3-2-1 support at nodes {sorted(set((pinned // 3).tolist()))}"
            )
        free_mask = np.ones(3 * n, bool)
        free_mask[(3 * fixed[:, None] + np.arange(3)).ravel()] = False
        free_mask[pinned] = False
        free_mask[p_dofs] = False
        pattern = CsrPattern.build(tets, n, free_mask)
        spring = np.zeros(3 * n)
        for jig in jigs:
            np.add.at(
                spring, (3 * jig.nodes[:, None] + np.arange(3)).ravel(), jig.stiffness_mn_per_mm
            )
        kernels.warm_up()  # compiled now, not inside the first state's timing
        return cls(
            rest=rest,
            tets=tets,
            young_modulus_kpa=float(E_kpa),
            poisson_ratio=float(nu),
            dm_inv=dm_inv,
            volumes_mm3=vol,
            k0=k0,
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

    # -- physics at a configuration x (n, 3) -------------------------------------------

    def rotations(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Element rotations (m, 3, 3) and volume ratios det F (m,) at x."""
        _, rot, det = self.kinematics(x)
        return rot, det

    def kinematics(
        self, x: np.ndarray, tangent: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Deformation gradients F (m, 3, 3), rotations R (m, 3, 3), det F (m,) at x. R is
        warm-started from the last call's (`kernels.kinematics`); elements it leaves, and
        all on the first call, take `corotation.polar_rotations`. `tangent` is Newton's
        hint that the tangent at x comes next (nothing to do here: it is applied
        matrix-free from F and R)."""
        guess = self.__dict__.get("_rot_guess")
        warm = guess is not None and guess.shape == (len(self.tets), 3, 3)
        f, rot, det, cold = kernels.kinematics(
            np.ascontiguousarray(x, dtype=float),
            self.tets,
            self.grads,
            guess if warm else np.empty((0, 3, 3)),
            warm,
            corotation.POLAR_WARM_ITERATIONS,
            corotation.POLAR_WARM_STOP,
        )
        if cold.any():
            rot[cold] = corotation.polar_rotations(f[cold])
        self.__dict__["_rot_guess"] = rot  # warm start of the next polar decomposition
        return f, rot, det

    @property
    def scatter(self) -> sp.csr_matrix:
        """Sparse (n, 4 m) operator summing per-element nodal rows into nodes."""
        s = self.__dict__.get("_scatter")
        if s is None:
            s = self.__dict__["_scatter"] = corotation.scatter_matrix(self.tets, self.n_nodes)
        return s

    def forces_and_energy(self, f: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, float]:
        """Elastic forces (n, 3) mN and strain energy (mN mm) from the deformation
        gradients and rotations (m, 3, 3) of `kinematics`."""
        lam, mu = self.lame_kpa
        return kernels.forces_and_energy(
            self.tets, self.grads, self.volumes_mm3, lam, mu, f, rot, *self.node_incidence
        )

    def apply_tangent(
        self, rot: np.ndarray, t_world: np.ndarray | None, v: np.ndarray
    ) -> np.ndarray:
        """The consistent tangent at rotations rot (m, 3, 3) with the rotation-derivative
        term t_world (m, 3, 3, `corotation.skew_stiffness`; None: SOFA's warped R K0 R^T)
        times v (n, 3); returns (n, 3) mN."""
        lam, mu = self.lame_kpa
        t = np.empty((0, 3, 3)) if t_world is None else np.ascontiguousarray(t_world)
        return kernels.tangent_product(
            self.tets,
            self.grads,
            self.volumes_mm3,
            lam,
            mu,
            np.ascontiguousarray(rot),
            t,
            t_world is not None,
            np.ascontiguousarray(v, dtype=float),
        )

    def apply_tangent_free(
        self,
        rot: np.ndarray,
        t_world: np.ndarray | None,
        v_free: np.ndarray,
        rg: np.ndarray | None = None,
    ) -> np.ndarray:
        """`apply_tangent` over the free dofs: v_free (n_free,) -> (n_free,) mN (the
        held dofs' components zero, their rows dropped), without full-size copies. rg:
        the rotated gradients of rot (`kernels.rotated_gradients`), if already at hand."""
        lam, mu = self.lame_kpa
        t = np.empty((0, 3, 3)) if t_world is None else np.ascontiguousarray(t_world)
        if rg is None:
            rg = kernels.rotated_gradients(self.grads, np.ascontiguousarray(rot))
        return kernels.tangent_product_dofs(
            self.tets,
            rg,
            self.volumes_mm3,
            lam,
            mu,
            t,
            t_world is not None,
            self.free_dof_map,
            np.ascontiguousarray(v_free, dtype=float),
            len(self.pattern.free),
            *self.node_incidence,
        )

    @functools.cached_property
    def extent_mm(self) -> float:
        """The rest body's largest side of its bounding box (mm)."""
        return float(np.ptp(self.rest, axis=0).max())

    @functools.cached_property
    def node_incidence(self) -> tuple[np.ndarray, np.ndarray]:
        """(ptr, rows) of `element_sums.node_incidence`: each node's element rows, in order."""
        return node_incidence(self.tets, self.n_nodes)

    @property
    def free_dof_map(self) -> np.ndarray:
        """(n, 3) int64: each node component's index among the free dofs, -1 if held."""
        d = self.__dict__.get("_free_dof_map")
        if d is None:
            d = np.full(3 * self.n_nodes, -1, np.int64)
            d[self.pattern.free] = np.arange(len(self.pattern.free))
            d = self.__dict__["_free_dof_map"] = d.reshape(self.n_nodes, 3)
        return d

    @property
    def lame_kpa(self) -> tuple[float, float]:
        return tet4.lame_parameters(self.young_modulus_kpa, self.poisson_ratio)

    @property
    def grads(self) -> np.ndarray:
        """(m, 4, 3) rest shape-function gradients (1/mm)."""
        g = self.__dict__.get("_grads")
        if g is None:
            g = np.empty((len(self.tets), 4, 3))
            g[:, 1:] = self.dm_inv
            g[:, 0] = -self.dm_inv.sum(axis=1)
            self.__dict__["_grads"] = g
        return g

    def tangent_blocks(
        self, rot: np.ndarray, f: np.ndarray | None, project: bool = True
    ) -> np.ndarray:
        """(m, 12, 12) element tangents: the consistent corotational tangent (projected
        to positive semi-definite per element) at F = f, or SOFA's warped R K0 R^T when
        f is None."""
        if f is None:
            return corotation.warped_stiffness(self.k0, rot)
        lam, mu = self.lame_kpa
        return corotation.exact_stiffness(self.grads, self.volumes_mm3, lam, mu, rot, f, project)

    def chamber_volumes(self, x: np.ndarray) -> np.ndarray:
        """(K,) cavity volumes (mm^3) at x: sum x0.(x1 x x2)/6 over each surface."""
        tris, owner = self._all_chamber_tris
        p = x[tris]
        a, b, c = p[:, 0], p[:, 1], p[:, 2]
        t = (
            a[:, 0] * (b[:, 1] * c[:, 2] - b[:, 2] * c[:, 1])
            + a[:, 1] * (b[:, 2] * c[:, 0] - b[:, 0] * c[:, 2])
            + a[:, 2] * (b[:, 0] * c[:, 1] - b[:, 1] * c[:, 0])
        )
        return np.bincount(owner, t, minlength=len(self.chamber_tris)) / 6.0

    def chamber_gradients(self, x: np.ndarray) -> np.ndarray:
        """(K, n, 3) H per chamber at x (mm^2): each triangle adds its area vector / 3 to
        its 3 vertices (`pressure.volume_gradient`, all chambers in one pass)."""
        tris, owner = self._all_chamber_tris
        k, n = len(self.chamber_tris), len(x)
        p = x[tris]
        u, v = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        slots = (owner[:, None] * n + tris).ravel()
        out = np.empty((k * n, 3))
        for c in range(3):
            c1, c2 = (c + 1) % 3, (c + 2) % 3
            area = (u[:, c1] * v[:, c2] - u[:, c2] * v[:, c1]) / 6.0
            out[:, c] = np.bincount(slots, np.repeat(area, 3), minlength=k * n)
        return out.reshape(k, n, 3)

    @property
    def _all_chamber_tris(self) -> tuple[np.ndarray, np.ndarray]:
        """All chambers' triangles (T, 3) and the chamber of each (T,)."""
        cat = self.__dict__.get("_cat")
        if cat is None:
            tris = (
                np.concatenate(self.chamber_tris)
                if self.chamber_tris
                else np.zeros((0, 3), np.int64)
            )
            owner = np.repeat(
                np.arange(len(self.chamber_tris)), [len(t) for t in self.chamber_tris]
            )
            cat = self.__dict__["_cat"] = (tris, owner)
        return cat

    def external_forces(
        self, x: np.ndarray, pressure_kpa: np.ndarray, load: Load, h: np.ndarray | None = None
    ) -> np.ndarray:
        """(n, 3) gravity + pressure (follower) + jig spring forces (mN) at x."""
        f = load.gravity * self.body_force_mn
        if len(self.chamber_tris):
            h = self.chamber_gradients(x) if h is None else h
            f = f + np.einsum("k,kni->ni", pressure_kpa, h)
        for jig in self.jigs:
            target = jig.targets(self.rest, load.jig)
            np.add.at(f, jig.nodes, jig.stiffness_mn_per_mm * (target - x[jig.nodes]))
        return f

    def load_stiffness(self, x: np.ndarray, pressure_kpa: np.ndarray) -> sp.csr_matrix | None:
        """Sparse (n_free, n_free) stiffness of the follower pressure, -sum_k p_k d^2V_k/dx^2
        (mN/mm), or None without chamber pressure."""
        if not len(self.chamber_tris) or not np.any(pressure_kpa):
            return None
        import scipy.sparse as sp

        keep, slot, indices, indptr = self._load_pattern
        vals = np.concatenate(
            [
                -pk * pressure.volume_hessian_values(x, t)
                for pk, t in zip(pressure_kpa, self.chamber_tris, strict=True)
            ]
        )
        data = np.bincount(slot, vals[keep], minlength=len(indices))
        n = len(self.pattern.free)
        return sp.csr_matrix((data, indices, indptr), shape=(n, n))

    @property
    def _load_pattern(self):
        """(keep, slot, indices, indptr): which entries of the chambers' volume Hessians
        (`pressure.volume_hessian_pattern`, chambers in turn) couple free dofs, where
        each lands in the CSR data of the load stiffness, and its CSR structure (fixed:
        filled by one bincount per Newton step instead of a COO conversion)."""
        pat = self.__dict__.get("_load_pat")
        if pat is None:
            parts = [pressure.volume_hessian_pattern(t) for t in self.chamber_tris]
            new = np.full(3 * self.n_nodes, -1, np.int64)
            new[self.pattern.free] = np.arange(len(self.pattern.free))
            r = new[np.concatenate([q[0] for q in parts])]
            c = new[np.concatenate([q[1] for q in parts])]
            keep = (r >= 0) & (c >= 0)
            n = len(self.pattern.free)
            uniq, slot = np.unique(r[keep] * n + c[keep], return_inverse=True)
            indptr = np.zeros(n + 1, np.int64)
            np.cumsum(np.bincount(uniq // n, minlength=n), out=indptr[1:])
            pat = self.__dict__["_load_pat"] = (
                keep,
                slot.reshape(-1),
                (uniq % n).astype(np.int32),
                indptr,
            )
        return pat

    def external_potential(self, x: np.ndarray, pressure_kpa: np.ndarray, load: Load) -> float:
        """Potential of the external loads at x (mN mm): springs minus gravity work minus
        p V per chamber (a constant pressure is conservative with H = dV/dx)."""
        e = -load.gravity * float(np.einsum("ni,ni->", self.body_force_mn, x - self.rest))
        if len(self.chamber_tris):
            e -= float(pressure_kpa @ self.chamber_volumes(x))
        for jig in self.jigs:
            d = x[jig.nodes] - jig.targets(self.rest, load.jig)
            e += 0.5 * jig.stiffness_mn_per_mm * float(np.einsum("ni,ni->", d, d))
        return e

    def internal_forces(self, x: np.ndarray, rot: np.ndarray) -> np.ndarray:
        """(n, 3) elastic forces (mN) at x with element rotations rot."""
        return corotation.forces_and_energy(x, self.rest, self.tets, self.k0, rot, self.scatter)[0]

    def min_det_f(self, x: np.ndarray) -> np.ndarray:
        """(m,) det F per tet at x."""
        return corotation.det3(corotation.deformation_gradients(x, self.tets, self.dm_inv))

    def mean_dilatation(self, x: np.ndarray) -> np.ndarray:
        """(m,) volume ratio of each tet at x: its det F (constant over a linear tet)."""
        return self.min_det_f(x)

    def make_solver(self, method: str = "pcg") -> TangentSolver:
        from fruitcli.fem.solver.linsolve import TangentSolver

        return TangentSolver(self, method)

    def map_points(self, tet_index: np.ndarray, bary: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Positions (t, 3), or (s, t, 3), of points given by tet and weights (t, 4)."""
        return np.einsum("...tai,ta->...ti", x[..., self.tets[tet_index], :], bary)

    def worst_element(self, det_f: np.ndarray) -> str:
        """'tet i at (x, y, z) mm (det F = ...)' for the most compressed element."""
        i = int(np.argmin(det_f))
        c = self.rest[self.tets[i]].mean(axis=0)
        return f"tet {i} at ({c[0]:.1f}, {c[1]:.1f}, {c[2]:.1f}) mm (det F = {det_f[i]:.3g})"


def _checked_mesh(
    nodes: ArrayLike, tets: ArrayLike, E_kpa: float, nu: float, min_quality: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rest (n, 3) mm, tets (m, 4) each with a positive volume, signed volumes (m,)
    mm^3 before the flips), or MeshError / SolverError naming what is wrong: the arrays,
    a sliver, E (kPa) or nu."""
    rest = np.ascontiguousarray(nodes, dtype=float)
    tets = np.ascontiguousarray(tets, dtype=np.int64)
    if rest.ndim != 2 or rest.shape[1] != 3 or not np.isfinite(rest).all():
        raise MeshError("nodes: expected a finite (N, 3) array in mm")
    if tets.ndim != 2 or tets.shape[1] != 4 or len(tets) == 0:
        raise MeshError("tets: expected a non-empty (M, 4) array")
    if tets.min() < 0 or tets.max() >= len(rest):
        raise MeshError("tets: node index out of range")
    if not E_kpa > 0:
        raise SolverError(f"[material].young_modulus_kpa: expected > 0, got {E_kpa}")
    if not -1.0 < nu < 0.5:
        raise SolverError(f"[material].poisson_ratio: expected -1 < nu < 0.5, got {nu}")
    vol = tet4.signed_volumes(rest, tets)
    flip = vol < 0
    if flip.any():
        tets = tets.copy()
        tets[flip] = tets[flip][:, [0, 2, 1, 3]]
    tet4.refuse_slivers(rest, tets, min_quality)
    return rest, tets, vol


def _chamber_surfaces(rest: np.ndarray, chambers: dict | None) -> tuple[list, list]:
    """(names, (t, 3) triangles oriented outward) of the chambers {name: triangles}."""
    n = len(rest)
    names, tris_list = [], []
    for name, tris in (chambers or {}).items():
        tris = np.asarray(tris, dtype=np.int64)
        if tris.ndim != 2 or tris.shape[1] != 3 or len(tris) < 4:
            raise MeshError(f"chamber {name}: expected a closed (T, 3) triangle surface")
        if tris.min() < 0 or tris.max() >= n:
            raise MeshError(f"chamber {name}: node index out of range")
        try:
            tris = pressure.orient_outward(rest, tris)
        except ValueError as exc:
            raise MeshError(f"chamber {name}: {exc}") from None
        names.append(str(name))
        tris_list.append(tris)
    return names, tris_list
