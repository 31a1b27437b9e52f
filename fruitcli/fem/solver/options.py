"""What one state solve is asked and gives back: the [solver] options
(`SolverOptions`), the converged state (`StateResult`), and the error of a state
stopped at its time budget (`OutOfTime`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fruitcli.errors import SolverError


@dataclass(frozen=True)
class SolverOptions:
    """`tolerance`: |r| <= tolerance * reference force; `max_iterations` per load step;
    `max_subdivisions`: halvings of a failing step; `load_steps`: initial steps.

    `max_seconds` (0: none): the time budget of one state (s); past it the state
    fails with `OutOfTime`.

    `displacement_tolerance_mm` (0: off): Newton also stops once the solver's kept
    factor estimates that the remaining correction moves no node by more than this
    (mm; pressure-controlled loads only, see `_close_enough`).

    A state also counts as converged when round-off keeps the residual from reaching
    the tolerance: the residual is within STALL_RESIDUAL_FACTOR of it and the full
    Newton correction moves no node by more than STEP_TOLERANCE times the body size
    (see `fruitcli.fem.tolerances`).

    `path_tolerance` (0: off): the relative residual the load steps short of the
    state's load are converged to when it is looser than `tolerance` (the last step
    converges to `tolerance`); when a later step then fails, the state is solved again
    from its start with every step to `tolerance` (`solver.state.PATH_TOLERANCE`; not
    a [solver] key: `fruit simulate` sets it for its first state).

    `stall_steps` (0: off): Newton gives up (`Stalled`) once this many steps in a row
    cut the relative residual by less than `tolerances.STALL_CUT` in all, far from the
    tolerance (not a [solver] key: the samples of a limit curve set it,
    `limits.STALL_STEPS`)."""

    tolerance: float = 1e-6
    max_iterations: int = 25
    max_subdivisions: int = 6
    linear_solver: str = "pcg"
    load_steps: int = 1
    displacement_tolerance_mm: float = 0.0
    max_seconds: float = 0.0
    path_tolerance: float = 0.0
    stall_steps: int = 0

    def __post_init__(self) -> None:
        """Refuse, with one line naming the [solver] key, an option that would make a
        state diverge, stop before solving or never end (SolverError)."""
        checks = (
            ("tolerance", 0.0 < self.tolerance < 1.0, "0 < tolerance < 1"),
            ("max_iterations", self.max_iterations >= 1, ">= 1"),
            ("max_subdivisions", self.max_subdivisions >= 0, ">= 0"),
            ("load_steps", self.load_steps >= 1, ">= 1"),
            ("displacement_tolerance_mm", self.displacement_tolerance_mm >= 0.0, ">= 0"),
            ("max_seconds", self.max_seconds >= 0.0, "a time budget > 0 s (0: none)"),
        )
        for key, ok, expected in checks:
            value = getattr(self, key)
            if not (ok and np.isfinite(value)):
                raise SolverError(f"[solver].{key}: expected {expected}, got {value!r}")


class OutOfTime(SolverError):
    """A state stopped at its time budget (`SolverOptions.max_seconds`); `fraction` is
    the part of the load step it had reached."""

    def __init__(self, message: str, fraction: float):
        super().__init__(message)
        self.fraction = fraction


class Stalled(SolverError):
    """Newton stopped where its steps no longer cut the residual
    (`SolverOptions.stall_steps`): like `OutOfTime`, the state is not tried again with
    shorter load steps."""


@dataclass
class StateResult:
    x: np.ndarray  # (n, 3) mm
    displacement_mm: np.ndarray  # (n, 3)
    pressure_kpa: np.ndarray  # (K,)
    chamber_volume_mm3: np.ndarray  # (K,)
    iterations: int
    residual: float  # relative, at convergence
    subdivisions: int
    min_det_f: float
    solve_ms: float
    kept: bool = False  # a curve's sample kept from an earlier run (`sample_cache`)
