"""Online mechanics for the live loop (the paper's online SOFA simulation): the body's
equilibrium at the chamber pressures just measured, instead of precomputed states
interpolated along their path (which is exact only for pressures on that path).

Each new pressure vector (kPa, one per chamber, in the model's chamber order) is solved
from the last equilibrium with one kept TangentSolver (its factorization and the
predictor's history), and the taxels follow by their barycentric coordinates. `run`
does this in a background thread so that the live loop never waits on the FEM: it
reads `taxels_mm`, the positions at the last solved pressures.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numba
import numpy as np

from fruitcli.errors import SolverError
from fruitcli.fem.fem_model import FemModel
from fruitcli.fem.solver.options import SolverOptions
from fruitcli.fem.solver.state import solve_state
from fruitcli.fem.state_load import Load

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from fruitcli.fem.reduced.model import ReducedModel

MIN_CHANGE_KPA = 0.05
"""Pressures that differ from the last solved ones by less than this in every chamber
are not solved again (a pressure sensor's noise is of this order)."""


class OnlineSolver:
    """Taxel positions (T, 3) mm at the latest chamber pressures. `update(p)` solves
    synchronously; `run(source, stop)` keeps solving the pressures `source()` returns
    until `stop` is set. A pressure the solver cannot reach (past what the body can
    carry) keeps the last positions and is counted in `failures` with `last_error`."""

    def __init__(
        self,
        model: FemModel,
        taxel_tet: np.ndarray,
        taxel_bary: np.ndarray,
        options: SolverOptions,
        first_options: SolverOptions | None = None,
        min_change_kpa: float = MIN_CHANGE_KPA,
    ):
        """`first_options`: for the first state, solved from rest (e.g. in the jig's
        load steps); default `options`."""
        self.model, self.options, self.min_change = model, options, min_change_kpa
        self.first_options = first_options or options
        self.tet, self.bary = np.asarray(taxel_tet), np.asarray(taxel_bary, float)
        self.solver = model.make_solver(options.linear_solver)
        self.x: np.ndarray | None = None  # None until the first solve (rest)
        self.p = np.zeros(len(model.chamber_names))
        self.load: Load | None = None
        self.solved_kpa: np.ndarray | None = None
        self.taxels_mm = model.map_points(self.tet, self.bary, model.rest)
        self.solve_ms: list[float] = []
        self.failures = 0
        self.last_error: str | None = None
        self.stopped: str | None = None  # why the thread of `run` ended early

    def update(self, pressure_kpa: ArrayLike | None) -> bool:
        """Solve at pressure_kpa (K,) unless it is None (nothing measured yet) or within
        `min_change_kpa` of the last pressures tried (solved or failed); returns whether
        new positions were published."""
        if pressure_kpa is None:
            return False
        p = np.array(pressure_kpa, float).reshape(-1)  # a copy: the source may reuse its array
        if len(p) != len(self.p):
            raise SolverError(
                f"online FEM: expected {len(self.p)} chamber pressures "
                f"({', '.join(self.model.chamber_names)}), got {len(p)}"
            )
        if self.solved_kpa is not None and np.all(np.abs(p - self.solved_kpa) < self.min_change):
            return False
        self.solved_kpa = p
        load = Load.pressures(p)
        opts = self.first_options if self.x is None else self.options
        try:
            res = solve_state(
                self.model,
                load,
                x_start=self.x,
                load_start=self.load,
                pressure_start=None if self.x is None else self.p,
                options=opts,
                solver=self.solver,
                label=f"online state at {np.round(p, 3).tolist()} kPa",
            )
        except SolverError as exc:
            self.failures += 1
            self.last_error = str(exc)
            return False
        self.x, self.p, self.load = res.x, res.pressure_kpa, load
        # one assignment: the live loop reads the old positions or the new, never half
        self.taxels_mm = self.model.map_points(self.tet, self.bary, res.x)
        self.solve_ms.append(res.solve_ms)
        return True

    def run(
        self, source: Callable[[], ArrayLike | None], stop: threading.Event, idle_s: float = 0.002
    ) -> threading.Thread:
        """Start a daemon thread solving the pressures `source()` returns (K,) kPa until
        `stop` is set; it sleeps `idle_s` whenever nothing changed."""

        def loop():
            # numba's thread count is per thread: one here, so that the element loops'
            # worker threads do not take the core the live loop runs on
            numba.set_num_threads(1)
            while not stop.is_set():
                try:
                    solved = self.update(source())
                except Exception as exc:
                    self.failures += 1
                    self.stopped = f"{type(exc).__name__}: {exc}"
                    return
                if not solved:
                    time.sleep(idle_s)

        th = threading.Thread(target=loop, daemon=True, name="online FEM")
        th.start()
        return th

    def summary(self) -> str:
        """One line: solves, median and max time per solve, failures."""
        if not self.solve_ms:
            text = f"online FEM: no state solved, {self.failures} failed"
            return text + (
                f"; the FEM thread stopped early ({self.stopped})" if self.stopped else ""
            )
        ms = np.array(self.solve_ms)
        plural = "s" if len(ms) != 1 else ""
        text = (
            f"online FEM: {len(ms)} state{plural} solved, {np.median(ms):.1f} ms median, "
            f"{ms.max():.1f} ms max, {self.failures} failed"
        )
        if self.stopped:
            text += f"; the FEM thread stopped early ({self.stopped})"
        return text.replace("online FEM:", "online FEM (full model):", 1) + (
            f" (last: {self.last_error})" if self.last_error else ""
        )


class ReducedOnline:
    """The live loop's taxels from the reduced model (`fruitcli.fem.reduced.model`): the same
    interface as OnlineSolver, but each pressure vector costs a matrix product (tens of
    us) instead of a Newton solve. A pressure vector outside the model's range is
    evaluated at the nearest pressures inside it (the fit does not extrapolate) and
    counted in `clamped`."""

    def __init__(self, reduced: ReducedModel):
        self.reduced, self.model = reduced, reduced  # .model.chamber_names, as OnlineSolver
        self.taxels_mm = reduced.taxels(np.clip(np.zeros(len(reduced.lo)), reduced.lo, reduced.hi))
        self.solved_kpa: np.ndarray | None = None
        self._last: list[float] | None = None
        self._lo, self._hi = reduced.lo.tolist(), reduced.hi.tolist()
        self.solve_ms: list[float] = []
        self.failures = 0
        self.clamped = 0
        self.stopped: str | None = None

    def update(self, pressure_kpa: ArrayLike | None) -> bool:
        """Evaluate at pressure_kpa (K,) unless None or unchanged; returns whether new
        positions were published."""
        if pressure_kpa is None:
            return False
        t0 = time.perf_counter()
        p = np.asarray(pressure_kpa, float).reshape(-1).tolist()  # a copy, in floats
        if len(p) != len(self._lo):
            raise SolverError(
                f"reduced model: expected {len(self._lo)} chamber "
                f"pressures ({', '.join(self.reduced.chamber_names)}), got {len(p)}"
            )
        if p == self._last:
            return False
        self._last = p
        self.solved_kpa = np.array(p)
        inside = [min(max(x, a), b) for x, a, b in zip(p, self._lo, self._hi, strict=True)]
        self.clamped += inside != p
        self.taxels_mm = self.reduced.taxels(inside)  # one assignment, as OnlineSolver
        self.solve_ms.append(1e3 * (time.perf_counter() - t0))
        return True

    run = OnlineSolver.run

    def summary(self) -> str:
        """One line: the model used, vectors evaluated, time per vector, clamped ones."""
        v = self.reduced.validation()
        head = (
            f"online reduced model (degree {v['degree']}, held-out taxel error max "
            f"{v['taxel_max_mm']:.2g} mm{'' if v['within_bound'] else ', OUTSIDE ITS BOUND'})"
        )
        if not self.solve_ms:
            text = f"{head}: no pressure vector evaluated"
        else:
            us = 1e3 * np.array(self.solve_ms)
            text = (
                f"{head}: {len(us)} pressure vectors, {np.median(us):.0f} us median, "
                f"{us.max():.0f} us max, {self.clamped} outside its range (clamped)"
            )
        return text + (f"; the thread stopped early ({self.stopped})" if self.stopped else "")
