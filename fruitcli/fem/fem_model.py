"""What every FEM model keeps: the protocol the Newton solver, the pressure limits, the
reduced model's build and the stages read of a model (`FemModel`), the one a model
solved from rest through softer bulk moduli adds (`BulkStaged`), and the protocol of
the linear solver a model makes for Newton (`LinearSolver`).

Two models keep it: the paper's corotational Hooke model on linear tets
(`corotational_model.Model`) and the hyperelastic one on any element
(`continuum.ContinuumModel`), whose solvers are `solver.linsolve.TangentSolver` and
`solver.continuum_linsolve.ContinuumSolver`. Units: mm, kPa, mN.
"""

from __future__ import annotations

from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    import scipy.sparse as sp

    from fruitcli.fem.materials.build import Material
    from fruitcli.fem.solver.assemble import CsrPattern
    from fruitcli.fem.state_load import Load

Kept = tuple[np.ndarray, np.ndarray, np.ndarray]
"""A converged state kept on a linear solver for the next state's start: (load vector
(`solver.predictor.load_vector`), x (n, 3) mm, chamber pressures (K,) kPa)."""


class LinearSolver(Protocol):
    """Solves with a model's tangent over the free dofs, set at an iterate by `update`;
    what Newton and the start of the next state read and set of it: `rtol` (relative
    residual its iterative solves stop at), `displacement_goal` (CG's (mm, relative
    residual) stop, `linsolve.pcg`), `near_tolerance` (Newton's chord steps, 0: none),
    `newton_c` (Newton's merit_new / merit^2, kept across states), `factor_seconds`
    (the last factorization's, s; 0: not looked ahead), `history` (the converged
    states kept), `sensitivity` ((dx/dp (n, 3, K), volume compliance (K, K) mm^3/kPa)
    of the first state, or None) and `estimated` (the last `estimate`: (r, factorizations
    then, its solve), or None)."""

    rtol: float
    displacement_goal: tuple[float, float]
    near_tolerance: float
    newton_c: float
    factor_seconds: float
    history: list[Kept]
    sensitivity: tuple[np.ndarray, np.ndarray] | None
    estimated: tuple[np.ndarray, int, np.ndarray] | None

    def update(
        self,
        rot: np.ndarray,
        f: np.ndarray | None = None,
        load_stiffness: sp.csr_matrix | None = None,
        project: bool = False,
    ) -> None: ...

    def solve(self, rhs: np.ndarray) -> np.ndarray: ...

    def estimate(self, r: np.ndarray) -> np.ndarray | None: ...


@runtime_checkable
class FemModel(Protocol):
    """A body ready to solve. `elements` is the full connectivity (4 or 10 nodes per
    tet), `tets` its corners; `element_name` and `material_name` the ``[fem].element``
    and ``[material].model`` it was built for. The Newton tuning a model carries:
    `escalate_on_damping` (a damped step switches to a safer tangent),
    `secant_while_rotating` (a turning jig's steps start from the secant predictor),
    `dilatation_step` (the largest change of an element's volume ratio per Newton step;
    0: no limit) and `bulk_stages()` (bulk moduli, kPa, a state solved from rest passes
    through first; none for the corotational model).

    What Newton evaluates at an iterate x (n, 3) mm: `kinematics` (the state the forces
    and the tangent are built from: (F, R, det F) or (x, x, det F)),
    `forces_and_energy`, the chambers' volumes and gradients, the external loads and
    their potential and stiffness; `pattern` holds the free dofs, `prescribed_dofs` and
    `prescribed_mm` the moved regions' dofs and full displacement (mm)."""

    rest: np.ndarray
    chamber_names: list[str]
    chamber_tris: list[np.ndarray]
    chamber_rest_volume_mm3: np.ndarray
    body_force_mn: np.ndarray
    jigs: list[Any]
    fixed_nodes: np.ndarray
    pinned_dofs: np.ndarray
    notes: list[str]
    pattern: CsrPattern
    prescribed_dofs: np.ndarray
    prescribed_mm: np.ndarray

    @property
    def tets(self) -> np.ndarray: ...

    @property
    def elements(self) -> np.ndarray: ...

    @property
    def element_name(self) -> str: ...

    @property
    def material_name(self) -> str: ...

    @property
    def n_nodes(self) -> int: ...

    @property
    def young_modulus_kpa(self) -> float: ...

    @property
    def escalate_on_damping(self) -> bool: ...

    @property
    def secant_while_rotating(self) -> bool: ...

    @property
    def dilatation_step(self) -> float: ...

    @property
    def extent_mm(self) -> float: ...

    def bulk_stages(self) -> list[float]: ...

    def make_solver(self, method: str = "pcg") -> LinearSolver: ...

    def kinematics(
        self, x: np.ndarray, tangent: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def forces_and_energy(self, f: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, float]: ...

    def external_forces(
        self, x: np.ndarray, pressure_kpa: np.ndarray, load: Load, h: np.ndarray | None = None
    ) -> np.ndarray: ...

    def external_potential(self, x: np.ndarray, pressure_kpa: np.ndarray, load: Load) -> float: ...

    def load_stiffness(self, x: np.ndarray, pressure_kpa: np.ndarray) -> sp.csr_matrix | None: ...

    def chamber_gradients(self, x: np.ndarray) -> np.ndarray: ...

    def mean_dilatation(self, x: np.ndarray) -> np.ndarray: ...

    def worst_element(self, det_f: np.ndarray) -> str: ...

    def chamber_volumes(self, x: np.ndarray) -> np.ndarray: ...

    def min_det_f(self, x: np.ndarray) -> np.ndarray: ...

    def map_points(self, tet_index: np.ndarray, bary: np.ndarray, x: np.ndarray) -> np.ndarray: ...


@runtime_checkable
class BulkStaged(FemModel, Protocol):
    """A model whose state from rest passes through softer bulk moduli first
    (`bulk_stages`; the hyperelastic one): its `material` and a context in which its
    bulk modulus is another (kPa)."""

    material: Material

    def bulk_modulus(self, kappa_kpa: float) -> AbstractContextManager[Any]: ...
