"""The moved [[fixed]] regions of a state: their dofs set to where the load puts them
(`impose_prescribed`), and the free dofs lifted along with them at a load step's start
(`lift_prescribed`)."""

from __future__ import annotations

import numpy as np

from fruitcli.fem.fem_model import FemModel, LinearSolver
from fruitcli.fem.state_load import Load


def impose_prescribed(model: FemModel, x: np.ndarray, load: Load) -> np.ndarray:
    """x with the prescribed dofs (moved [[fixed]] regions) at rest + load.prescribed *
    displacement (a copy when anything is prescribed)."""
    if not len(model.prescribed_dofs):
        return x
    x = np.array(x, float)
    flat = x.reshape(-1)
    flat[model.prescribed_dofs] = (
        model.rest.reshape(-1)[model.prescribed_dofs] + load.prescribed * model.prescribed_mm
    )
    return x


LIFT_FRACTION = 1e-3
"""`lift_prescribed` measures the forces of the prescribed motion over this fraction of
it (small enough to stay linear and invert nothing)."""


def lift_prescribed(
    model: FemModel, solver: LinearSolver, x: np.ndarray, load_a: Load, load_b: Load
) -> np.ndarray:
    """Start of a load step that moves prescribed dofs: the free dofs follow the motion
    by one linear solve with the tangent at x, K_ff dx_f = -K_fp dx_p (K_fp dx_p from
    the forces over LIFT_FRACTION of the motion), so that moving a clamp inverts no
    element next to it. x itself when nothing moves."""
    dp = (load_b.prescribed - load_a.prescribed) * model.prescribed_mm
    if not np.any(dp):
        return x
    free = model.pattern.free
    kin = model.kinematics(x)
    f0 = model.forces_and_energy(kin[0], kin[1])[0].reshape(-1)[free].copy()
    xe = np.array(x, float)
    xe.reshape(-1)[model.prescribed_dofs] += LIFT_FRACTION * dp
    kin_e = model.kinematics(xe)
    f1 = model.forces_and_energy(kin_e[0], kin_e[1])[0].reshape(-1)[free]
    kin = model.kinematics(x)
    solver.update(kin[1], kin[0], None, True)
    dx = solver.solve(-(f1 - f0) / LIFT_FRACTION)
    out = np.array(x, float)
    out.reshape(-1)[free] += dx
    out.reshape(-1)[model.prescribed_dofs] += dp
    return out
