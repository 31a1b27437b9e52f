"""The samples of the chambers' pressure-volume curves that the pressure check solved
(`fruitcli.fem.pressure_check.check_pressures`), kept in the output folder so that a
later run on the same body reuses them instead of solving them again (`SampleCache`):
a scene edited only in its pressures is refused, or passed, within a second or two of
the mesh instead of solving its first sample from rest again (on the default Fruit 9
Newton steps under the body's weight). `fruit simulate` keeps its first state (solved
from rest) there too, and a later run on the same body starts from it
(`kept_first_state`).

A kept sample is looked at only when the file's key is the body's (mesh, element,
material, density and gravity, supports, jigs, chambers: `body_key`), its entry's key
the load's and tolerance's, and its supported and moved dofs where the load puts them.
It is used as it is when it is an equilibrium of the model as it is now (no element
inverted, the relative residual and volume error within the tolerance: Newton's own
test at the sample's forces); otherwise Newton starts from it, and it is dropped when
Newton finds no equilibrium there. A stale, edited or unreadable file is ignored and
written anew. Units: mm, kPa.
"""

from __future__ import annotations

import dataclasses
import hashlib
import time
import zipfile
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from fruitcli.errors import SolverError
from fruitcli.fem.fem_model import FemModel, LinearSolver
from fruitcli.fem.io import save_npz
from fruitcli.fem.solver.newton import NewtonStep
from fruitcli.fem.solver.options import SolverOptions, StateResult
from fruitcli.fem.solver.predictor import load_vector, remember, remember_sensitivity
from fruitcli.fem.solver.prescribed import impose_prescribed
from fruitcli.fem.solver.state import _reference_force, solve_state
from fruitcli.fem.state_load import Load
from fruitcli.fem.tolerances import FORCE_FLOOR

CACHE_FILE = "pressure-check.npz"
"""The kept samples' file in a `fruit simulate` output folder."""


def _digest(parts: list) -> str:
    """sha256 (hex) of arrays and plain values, each with its type, shape and bytes."""
    h = hashlib.sha256()
    for part in parts:
        if isinstance(part, np.ndarray):
            a = np.ascontiguousarray(part)
            h.update(f"{a.dtype.str}{a.shape}".encode())
            h.update(a.tobytes())
        else:
            h.update(repr(part).encode())
        h.update(b"|")
    return h.hexdigest()


def body_key(model: FemModel) -> str:
    """The key of everything a sample's equilibrium depends on besides its load: rest
    nodes, elements and their family, the material, the body force, the fixed, pinned
    and moved dofs, the jigs and the chamber walls."""
    parts: list = [
        type(model).__name__,
        getattr(model, "element_name", ""),
        repr(getattr(model, "material", None)),
        model.young_modulus_kpa,
        getattr(model, "poisson_ratio", None),
        model.rest,
        model.elements,
        model.body_force_mn,
        model.fixed_nodes,
        model.pinned_dofs,
        model.prescribed_dofs,
        model.prescribed_mm,
        *model.chamber_tris,
    ]
    for jig in model.jigs:
        parts += [np.asarray(getattr(jig, f.name)) for f in dataclasses.fields(jig)]
    return _digest(parts)


def load_key(load: Load, tolerance: float) -> str:
    """The key of one sample: its load's fields and the tolerance it was solved to."""
    fields = [getattr(load, f.name) for f in dataclasses.fields(load)]
    return _digest([np.asarray(v) if v is not None else "none" for v in fields] + [tolerance])[:32]


class SampleCache:
    """The curves' samples of one body kept in `path` (npz, no pickles): `get` a load's
    sample when kept and still an equilibrium, `put` a solved one, `save` them."""

    def __init__(self, model: FemModel, path: Path, options: SolverOptions):
        self.model, self.path, self.options = model, Path(path), options
        self.tolerance = options.tolerance
        self.key = body_key(model)
        self.entries: dict[str, tuple[np.ndarray, np.ndarray, float]] = {}
        # an entry's Newton constant C (`LinearSolver.newton_c`), when kept with it
        self.newton_c: dict[str, float] = {}
        self.changed = False
        self._read()

    def _read(self) -> None:
        """The file's entries when its key is the body's (none otherwise)."""
        try:
            with np.load(self.path, allow_pickle=False) as data:
                if str(data["body"]) != self.key:
                    return
                for name in data.files:
                    if name.endswith("_x"):
                        k = name[:-2]
                        self.entries[k] = (data[name], data[k + "_p"], float(data[k + "_ms"]))
                        if k + "_c" in data.files:
                            self.newton_c[k] = float(data[k + "_c"])
        except (OSError, KeyError, ValueError, zipfile.BadZipFile):
            self.entries, self.newton_c = {}, {}

    def get(
        self, load: Load, solver: LinearSolver, tolerance: float | None = None
    ) -> StateResult | None:
        """The kept sample under `load` solved to `tolerance` (default: the cache's;
        marked `kept`, its solve time the original's, which sets the next samples'
        budget as it did then): as it is when it is an equilibrium to that tolerance by
        Newton's test at its own forces, else after Newton's steps from it; None when
        none is kept, its supports moved, or Newton finds no equilibrium from it."""
        tolerance = tolerance or self.tolerance
        entry = self.entries.get(load_key(load, tolerance))
        if entry is None:
            return None
        x, p, ms = entry
        m = self.model
        if x.shape != m.rest.shape or p.shape != (len(m.chamber_tris),) or not np.isfinite(x).all():
            return None
        held = np.ones(3 * m.n_nodes, bool)
        held[m.pattern.free] = False
        placed = impose_prescribed(m, m.rest, load).reshape(-1)
        if not np.array_equal(x.reshape(-1)[held], placed[held]):
            return None
        pk = p.copy()
        vc = np.asarray(load.volume_controlled, bool)
        pk[~vc] = load.pressure_kpa[~vc]
        scale = FORCE_FLOOR * m.young_modulus_kpa * m.extent_mm**2
        step = NewtonStep(m, solver, load, _reference_force(m, x, pk, load, load, scale))
        now = step.evaluate(x, pk)  # Newton's own relative residual and volume error
        if np.isfinite(now.energy) and now.merit <= tolerance:
            volumes = m.chamber_volumes(x)
            det = float(now.det_f.min())
            return StateResult(x, x - m.rest, pk, volumes, 0, now.merit, 0, det, ms, kept=True)
        try:
            opts = replace(self.options, tolerance=tolerance, load_steps=1)
            res = solve_state(m, load, x, load, pk, opts, solver, "kept sample")
        except SolverError:
            return None
        return dataclasses.replace(res, solve_ms=max(res.solve_ms, ms), kept=True)

    def put(
        self,
        load: Load,
        res: StateResult,
        newton_c: float | None = None,
        tolerance: float | None = None,
    ) -> None:
        """Keep the sample `res` under `load` (solved to `tolerance`, default the
        cache's, or a kept one Newton moved), with the solver's Newton constant after it
        when given."""
        key = load_key(load, tolerance or self.tolerance)
        if key not in self.entries or res.iterations:
            self.entries[key] = (res.x, res.pressure_kpa, res.solve_ms)
            if newton_c is not None:
                self.newton_c[key] = float(newton_c)
            self.changed = True

    def save(self) -> None:
        """Write the kept samples (when any was added) through a temporary file; a
        folder that cannot be written keeps none."""
        if not self.changed:
            return
        arrays: dict[str, np.ndarray] = {"body": np.array(self.key)}
        for k, (x, p, ms) in self.entries.items():
            arrays.update({k + "_x": x, k + "_p": p, k + "_ms": np.array(ms)})
            if k in self.newton_c:
                arrays[k + "_c"] = np.array(self.newton_c[k])
        try:
            save_npz(self.path, arrays)
        except OSError:
            return
        self.changed = False


def kept_or_solved(
    samples: SampleCache | None,
    load: Load,
    solver: LinearSolver,
    solve: Callable[[], StateResult],
    tolerance: float | None = None,
) -> StateResult:
    """The sample under `load` solved to `tolerance` (default: the cache's): kept in
    `samples` (`SampleCache.get`), else `solve()`'s, then kept there."""
    res = samples.get(load, solver, tolerance) if samples is not None else None
    if res is None:
        res = solve()
    if samples is not None:
        samples.put(load, res, tolerance=tolerance)
    return res


def kept_first_state(
    model: FemModel, load: Load, solver: LinearSolver, first: SampleCache | None
) -> StateResult | None:
    """The first state under `load` as an earlier run on the same body kept it in
    `first` (`SampleCache.get`: as it is when still an equilibrium of the model to the
    states' tolerance, else after Newton's steps from it), its solve time this run's,
    with the solver left as a state solved from rest leaves it for the next state's
    predictor (the state kept, the chambers' pressure response there with its full
    tangent, `predictor.remember_sensitivity`) and for the next states' linear
    tolerance (the Newton constant kept with the state: without it the default Fruit's
    12 later states took 3.2 s instead of 2.8 s, one refactorizing); None when none is
    kept or it is no longer an equilibrium."""
    key = None if first is None else load_key(load, first.tolerance)
    if first is None or key not in first.entries:
        return None
    t0 = time.perf_counter()
    # the kept factor (of rest, or none) is far from the state's tangent: CG would only
    # find that out before refactoring (Newton's steps from the state, or the tangent
    # there for the pressure response)
    if hasattr(solver, "refresh"):
        solver.refresh = True
    res = first.get(load, solver)
    if res is None:
        return None
    if not solver.history:
        solver.history = remember([], load_vector(load), res.x, res.pressure_kpa)
    if key in first.newton_c and not solver.newton_c:
        solver.newton_c = first.newton_c[key]  # the next states' first linear tolerance
    if solver.sensitivity is None and len(model.chamber_tris):
        # the tangent Newton's last step would have left (the follower-pressure
        # stiffness included), then the chambers' pressure response with it
        f, rot, _ = model.kinematics(res.x)
        solver.update(rot, f, model.load_stiffness(res.x, res.pressure_kpa), False)
        remember_sensitivity(model, solver, res.x, load, 1)
    return replace(res, solve_ms=1e3 * (time.perf_counter() - t0))
