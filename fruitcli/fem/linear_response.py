"""Where a body's pressure-volume curves start (`Start`): its equilibrium under its
weight, and the chambers' linear pressure response there (`response`), from which each
curve's first sample is guessed. Units: mm, mm^3, kPa."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from fruitcli.fem.fem_model import FemModel, LinearSolver


@dataclass
class Start:
    """Where every curve of a body starts: its equilibrium under its weight (rest when it
    carries none), x (n, 3) mm with chamber volumes (K,) mm^3 there, and the chambers'
    pressure response there: dx/dp (n, 3, K) mm/kPa and the compliance dV/dp (K, K)
    mm^3/kPa (`response`)."""

    x: np.ndarray
    volume_mm3: np.ndarray
    dx_dp: np.ndarray
    compliance: np.ndarray


def response(model: FemModel, solver: LinearSolver, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(dx/dp (n, 3, K) mm/kPa, dV/dp (K, K) mm^3/kPa) of the chambers at the
    configuration x with their pressures at 0 (no follower-pressure stiffness), by one
    solve with the tangent there on `solver` (its kept factor refreshed when CG needs
    it)."""
    free = model.pattern.free
    k = len(model.chamber_tris)
    kin = model.kinematics(x)
    solver.update(kin[1], kin[0], None, False)
    h = model.chamber_gradients(x).reshape(k, -1)[:, free]
    cols = solver.solve(np.ascontiguousarray(h.T)).reshape(len(free), k)
    dx = np.zeros((3 * model.n_nodes, k))
    dx[free] = cols
    return dx.reshape(model.n_nodes, 3, k), h @ cols
