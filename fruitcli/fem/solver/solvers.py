"""The linear solvers of a Newton step, one table (``[solver].linear_solver``).

The scene schema's choices and both tangent solvers (`linsolve`, `continuum_linsolve`)
read `LINEAR_SOLVERS`. This module imports nothing, so the scene schema can read it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class LinearSolver:
    """A strategy for K_t dx = b (see `linsolve`'s docstring for each)."""

    name: str
    doc: str


LINEAR_SOLVERS: dict[str, LinearSolver] = {
    s.name: s
    for s in (
        LinearSolver("pcg", "CG preconditioned by a kept Cholesky factor (default)"),
        LinearSolver("direct", "the tangent assembled and factorized at every iteration"),
        LinearSolver("jacobi", "CG with a Jacobi preconditioner, no factorization"),
    )
}
