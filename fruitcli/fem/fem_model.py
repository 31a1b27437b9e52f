"""What every FEM model keeps: the protocol the Newton solver, the pressure limits, the
reduced model's build and the stages read of a model.

Two models keep it: the paper's corotational Hooke model on linear tets
(`corotational_model.Model`) and the hyperelastic one on any element
(`continuum.ContinuumModel`). Units: mm, kPa, mN.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class FemModel(Protocol):
    """A body ready to solve. `elements` is the full connectivity (4 or 10 nodes per
    tet), `tets` its corners; `element_name` and `material_name` the ``[fem].element``
    and ``[material].model`` it was built for. The Newton tuning a model carries:
    `escalate_on_damping` (a damped step switches to a safer tangent),
    `secant_while_rotating` (a turning jig's steps start from the secant predictor),
    `dilatation_step` (the largest change of an element's volume ratio per Newton step;
    0: no limit) and `bulk_stages()` (bulk moduli, kPa, a state solved from rest passes
    through first; none for the corotational model)."""

    rest: np.ndarray
    chamber_names: list[str]
    chamber_tris: list[np.ndarray]
    chamber_rest_volume_mm3: np.ndarray
    body_force_mn: np.ndarray
    jigs: list[Any]
    fixed_nodes: np.ndarray
    pinned_dofs: np.ndarray
    notes: list[str]

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

    def bulk_stages(self) -> list[float]: ...

    def make_solver(self, method: str = "pcg") -> Any: ...

    def chamber_volumes(self, x: np.ndarray) -> np.ndarray: ...

    def min_det_f(self, x: np.ndarray) -> np.ndarray: ...

    def map_points(self, tet_index: np.ndarray, bary: np.ndarray, x: np.ndarray) -> np.ndarray: ...
