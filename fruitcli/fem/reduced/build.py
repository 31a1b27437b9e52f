"""Building the reduced model (`fruitcli.fem.reduced.model`) from full solves, once per mesh,
material and pressure range (kPa, mm).

1. Full solves at a Chebyshev-Lobatto tensor grid of `points_per_axis` pressures per
   chamber over the box, in snake order: each solve starts from the previous sample,
   one grid step away (the first from rest).
2. The total degree (<= max_degree, < points_per_axis) is the one with the smallest
   leave-one-out taxel error over the grid samples: chosen without the held-out set.
3. Held-out validation: full solves at `validation` uniformly random pressure vectors
   (seeded), each from the nearest solved state; the errors of the chosen fit there
   are stored with the model, with the same figures for every degree and for the
   nested coarser grids (error against degree and number of samples).

The reduce stage (`run_reduce`) reads the scene once, into `ReduceInputs`
(`reduce_inputs`); everything below it takes those typed inputs.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import SceneError, SolverError
from fruitcli.fem.fem_model import FemModel
from fruitcli.fem.reduced import response_surface as rs
from fruitcli.fem.reduced.model import ReducedModel
from fruitcli.fem.solver.options import SolverOptions, StateResult
from fruitcli.fem.solver.state import solve_state
from fruitcli.fem.state_load import Load

if TYPE_CHECKING:
    from fruitcli.scene import Scene

POD_TOLERANCE_MM = 1e-4
"""The nodes' POD keeps modes until no sample's node moves by more than this (mm) from
its projection: far below the fit's own error."""


def _noop(msg: str) -> None:
    pass


@dataclass(frozen=True)
class PressureBoxInputs:
    """What the pressure box is made of (`pressure_range`): [reduced].pressure_range_kpa
    (lo, hi) kPa or None; [reduced].margin (a share of each chamber's span); the
    [actuation] pressures per chamber (kPa, one per state); whether [actuation] grows
    chamber volumes instead."""

    range_kpa: tuple[float, float] | None
    margin: float
    pressure_kpa: dict[str, tuple[float, ...]]
    volume_controlled: bool


def pressure_box_inputs(scene: Scene) -> PressureBoxInputs:
    """The pressure box's inputs from a validated scene."""
    cfg, act = scene.reduced, scene.actuation
    rng = cfg.pressure_range_kpa
    table = act.pressure_kpa or {}
    return PressureBoxInputs(
        range_kpa=None if rng is None else (float(rng[0]), float(rng[1])),
        margin=float(cfg.margin),
        pressure_kpa={str(n): tuple(np.atleast_1d(np.asarray(v, float))) for n, v in table.items()},
        volume_controlled=bool(act.volume_growth_mm3),
    )


def pressure_box(scene: Scene, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """The scene's pressure box (`pressure_range` of `pressure_box_inputs`), which the
    reduce stage's inputs hash (`workflow.fem_stages`)."""
    return pressure_range(pressure_box_inputs(scene), names)


def pressure_range(box: PressureBoxInputs, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) (K,) kPa of the chambers `names`: the pressure range for every chamber,
    else each chamber's [actuation] pressures widened by the margin of their span (of
    the largest chamber's span for a chamber held at one pressure); SceneError in one
    line when there is neither or [actuation] controls volumes."""
    k = len(names)
    if box.range_kpa is not None:
        return np.full(k, box.range_kpa[0]), np.full(k, box.range_kpa[1])
    if box.volume_controlled:
        raise SceneError(
            "[actuation].volume_growth_mm3: the reduced model maps pressures; "
            "give [reduced].pressure_range_kpa = [lo, hi] (kPa)"
        )
    table = box.pressure_kpa
    if not table:
        raise SceneError(
            "[reduced]: no pressure range: give [reduced].pressure_range_kpa = "
            "[lo, hi] (kPa) or [actuation].pressure_kpa"
        )
    values = [np.asarray(table.get(n, [0.0]), float) for n in names]
    lo = np.array([v.min() for v in values])
    hi = np.array([v.max() for v in values])
    span = hi - lo
    span = np.where(span > 0, span, span.max())
    if span.max() <= 0:
        raise SceneError(
            "[actuation].pressure_kpa: every chamber at one pressure: give "
            "[reduced].pressure_range_kpa = [lo, hi] (kPa)"
        )
    m = box.margin
    return lo - m * span, hi + m * span


@dataclass(frozen=True)
class ReduceInputs:
    """What the reduce stage reads of the scene besides the model and the solver: the
    pressure box's inputs and [reduced]'s points_per_axis, max_degree (of the response
    surfaces), validation (held-out full solves) and seed (of their pressures)."""

    box: PressureBoxInputs
    points_per_axis: int
    max_degree: int
    validation: int
    seed: int


def reduce_inputs(scene: Scene) -> ReduceInputs:
    """The reduce stage's inputs from a validated scene."""
    cfg = scene.reduced
    return ReduceInputs(
        pressure_box_inputs(scene),
        int(cfg.points_per_axis),
        int(cfg.max_degree),
        int(cfg.validation),
        int(cfg.seed),
    )


class _Solves:
    """Full solves kept with their states, each started from the nearest solved one
    (the first from rest with `first_options`); `progress` hears of each of the
    `total`."""

    def __init__(
        self,
        model: FemModel,
        options: SolverOptions,
        first_options: SolverOptions,
        progress: Callable[[str], None],
        total: int,
    ):
        self.model, self.options, self.first = model, options, first_options
        self.solver = model.make_solver(options.linear_solver)
        self.progress, self.total = progress, total
        self.p: list[np.ndarray] = []
        self.x: list[np.ndarray] = []
        self.results: list[StateResult] = []

    def solve(self, p: np.ndarray) -> StateResult:
        """The equilibrium under chamber pressures p (K,) kPa, kept."""
        load = Load.pressures(p)
        x_start, load_start, pressure_start, options = None, None, None, self.first
        if self.p:
            j = int(np.argmin(np.linalg.norm(np.array(self.p) - p, axis=1)))
            x_start, pressure_start, options = self.x[j], self.p[j], self.options
            load_start = Load.pressures(self.p[j])
        try:
            res = solve_state(
                self.model,
                load,
                x_start,
                load_start,
                pressure_start,
                options,
                self.solver,
                f"reduced-model sample at {np.round(p, 3).tolist()} kPa",
            )
        except SolverError as exc:
            raise SolverError(
                f"{exc} (narrow [reduced].pressure_range_kpa or [reduced].margin)"
            ) from None
        self.p.append(np.array(p, float))
        self.x.append(res.x)
        self.results.append(res)
        self.progress(
            f"state {len(self.p)}/{self.total}: full solve at "
            f"{np.round(p, 2).tolist()} kPa, {res.iterations} iterations, "
            f"{res.solve_ms:.0f} ms"
        )
        return res


def _outputs(
    model: FemModel, solves: _Solves, idx: np.ndarray, tet: np.ndarray, w: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(taxels (n, 3T), volumes (n, K), displacements (n, 3N)) of solves[idx]."""
    x = np.stack([solves.x[i] for i in idx])
    taxels = model.map_points(tet, w, x).reshape(len(idx), -1)
    vol = np.stack([solves.results[i].chamber_volume_mm3 for i in idx]).reshape(len(idx), -1)
    return taxels, vol, (x - model.rest).reshape(len(idx), -1)


def taxel_errors(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """(n, T) distance (mm) between taxel rows (n, 3T)."""
    return np.linalg.norm((pred - true).reshape(len(pred), -1, 3), axis=2)


def volume_errors(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """(n, K) |error| in % of the full model's volume."""
    return 100.0 * np.abs(pred - true) / np.maximum(np.abs(true), 1e-12)


def _pod(u: np.ndarray) -> np.ndarray:
    """(r, 3N) orthonormal modes of the displacement rows u (n, 3N), as few as keep
    every row within POD_TOLERANCE_MM of its projection."""
    _, s, vt = np.linalg.svd(u, full_matrices=False)
    for r in range(1, len(s) + 1):
        left = u - (u @ vt[:r].T) @ vt[:r]
        if np.abs(left).max() <= POD_TOLERANCE_MM:
            return vt[:r]
    return vt


def build(
    model: FemModel,
    taxel_tet: np.ndarray,
    taxel_bary: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    options: SolverOptions,
    first_options: SolverOptions,
    *,
    points_per_axis: int = 5,
    max_degree: int = 4,
    validation: int = 50,
    seed: int = 0,
    surface_nodes: np.ndarray | None = None,
    extra: dict[str, np.ndarray] | None = None,
    progress: Callable[[str], None] | None = None,
) -> ReducedModel:
    """Fit and validate the reduced model of `model` over the box [lo, hi] (K,) kPa for
    the taxels in elements taxel_tet (T,) at barycentric taxel_bary (T, 4); the solver
    options of later samples and of the first (from rest). `extra`: arrays stored
    beside it (mesh, element names). Raises SolverError naming the sample pressure
    when a full solve fails."""
    progress = progress or _noop
    t0 = time.perf_counter()
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    k, n = len(lo), int(points_per_axis)
    _check_box(lo, hi, n, max_degree, validation)
    grid_idx = rs.snake_grid(k, n)
    xi_grid = rs.lobatto_points(n)[grid_idx]
    p_grid = lo + (xi_grid + 1.0) / 2.0 * (hi - lo)
    rng = np.random.default_rng(seed)
    p_val = lo + rng.random((validation, k)) * (hi - lo)
    solves = _Solves(model, options, first_options, progress, len(p_grid) + validation)
    grid_rows, val_rows = _solve_samples(solves, p_grid, p_val)
    fit_s = time.perf_counter()
    tax_g, vol_g, u_g = _outputs(model, solves, grid_rows, taxel_tet, taxel_bary)
    tax_v, vol_v, u_v = _outputs(model, solves, val_rows, taxel_tet, taxel_bary)
    xi_val = rs.scale(p_val, lo, hi)
    degrees, loo_max, study = _degree_study(
        xi_grid, grid_idx, xi_val, (tax_g, vol_g), (tax_v, vol_v), n, max_degree
    )
    degree = degrees[int(np.argmin(loo_max))]
    exps = rs.exponents(k, degree)
    phi_g = rs.basis(xi_grid, exps)
    coef_taxels = rs.fit(phi_g, tax_g)
    coef_volume = rs.fit(phi_g, vol_g)
    modes = _pod(u_g)
    coef_modes = rs.fit(phi_g, u_g @ modes.T)
    phi_v = rs.basis(xi_val, exps)
    err_tax = taxel_errors(phi_v @ coef_taxels, tax_v)
    err_vol = volume_errors(phi_v @ coef_volume, vol_v)
    surf = (
        np.arange(len(model.rest)) if surface_nodes is None else np.asarray(surface_nodes, np.int64)
    )
    u_pred = (phi_v @ coef_modes) @ modes
    err_surf = np.linalg.norm((u_pred - u_v).reshape(validation, -1, 3)[:, surf], axis=2)
    solve_ms = np.array([r.solve_ms for r in solves.results])
    arrays = dict(extra or {})
    arrays.update(
        chamber_names=np.array(model.chamber_names, dtype=str).reshape(-1),
        range_lo_kpa=lo,
        range_hi_kpa=hi,
        exponents=exps,
        coef_taxels=coef_taxels,
        coef_volume=coef_volume,
        coef_modes=coef_modes,
        modes=modes,
        rest_nodes=model.rest,
        surface_node_index=surf,
        taxel_tet=np.asarray(taxel_tet),
        taxel_bary=np.asarray(taxel_bary, float),
        sample_kpa=p_grid,
        validation_kpa=p_val,
        validation_taxel_error_mm=err_tax,
        validation_volume_error_pct=err_vol,
        validation_surface_error_mm=err_surf,
        loo_degrees=np.array(degrees),
        loo_taxel_max_mm=np.array(loo_max),
        study=np.array(study, float).reshape(-1, 5),  # points/axis, degree, samples, mm, %
        full_solves=np.array(len(solves.results)),
        solve_ms=solve_ms,
        fit_s=np.array(time.perf_counter() - fit_s),
        build_s=np.array(0.0),
    )
    arrays["build_s"] = np.array(time.perf_counter() - t0)
    return ReducedModel.from_arrays(arrays)


def _check_box(lo: np.ndarray, hi: np.ndarray, n: int, max_degree: int, validation: int) -> None:
    """Refuse a box [lo, hi] (K,) kPa without chambers or empty, and settings that fit
    nothing."""
    k = len(lo)
    if k == 0:
        raise SceneError("[reduced]: the body has no chambers: nothing to reduce")
    if n < 2 or max_degree < 1 or validation < 1:
        raise SceneError(
            "[reduced]: expected points_per_axis >= 2, max_degree >= 1, validation >= 1"
        )
    if np.any(hi <= lo):
        raise SceneError(f"[reduced]: empty pressure range {lo.tolist()}..{hi.tolist()} kPa")


def _solve_samples(
    solves: _Solves, p_grid: np.ndarray, p_val: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Solve the grid's pressures (S, K) kPa, then the held-out ones (V, K); -> the rows
    of `solves` that hold each."""
    validation = len(p_val)
    # the grid from its corner nearest rest (snake order from the zero-pressure end)
    if np.linalg.norm(p_grid[-1]) < np.linalg.norm(p_grid[0]):
        order = np.arange(len(p_grid))[::-1]
    else:
        order = np.arange(len(p_grid))
    for i in order:
        solves.solve(p_grid[i])
    grid_rows = np.empty(len(p_grid), np.int64)
    grid_rows[order] = np.arange(len(p_grid))
    # held-out vectors along a nearest-neighbour path, each from the nearest solved state
    todo, prev = list(range(validation)), p_grid[order[-1]]
    val_rows = np.empty(validation, np.int64)
    while todo:
        j = min(todo, key=lambda v: np.linalg.norm(p_val[v] - prev))
        todo.remove(j)
        solves.solve(p_val[j])
        val_rows[j] = len(solves.p) - 1
        prev = p_val[j]
    return grid_rows, val_rows


def _degree_study(
    xi_grid: np.ndarray,
    grid_idx: np.ndarray,
    xi_val: np.ndarray,
    grid: tuple[np.ndarray, np.ndarray],
    held_out: tuple[np.ndarray, np.ndarray],
    n: int,
    max_degree: int,
) -> tuple:
    """(degrees, the grid's leave-one-out taxel error (mm) of each, the study rows
    [points/axis, degree, samples, taxel mm, volume %] on held-out pressures) of the fits
    to `grid` = (taxels, volumes) at the grid points `xi_grid` (S, K) in [-1, 1], checked
    against `held_out` = (taxels, volumes) at `xi_val`; `n` points per axis."""
    (tax_g, vol_g), (tax_v, vol_v) = grid, held_out
    k = xi_grid.shape[1]
    # degree by leave-one-out on the grid; the held-out figures for every degree and
    # nested coarser grid are kept for the report
    degrees = list(range(1, min(max_degree, n - 1) + 1))
    loo_max, study = [], []
    for d in degrees:
        phi = rs.basis(xi_grid, rs.exponents(k, d))
        loo = rs.leave_one_out(phi, np.hstack([tax_g, vol_g]))
        loo_max.append(float(taxel_errors(loo[:, : tax_g.shape[1]], 0 * tax_g).max()))
    for m in [m for m in range(2, n + 1) if (n - 1) % (m - 1) == 0]:
        step = (n - 1) // (m - 1)
        keep = np.all(grid_idx % step == 0, axis=1)
        for d in range(1, min(max_degree, m - 1) + 1):
            exps = rs.exponents(k, d)
            c = rs.fit(rs.basis(xi_grid[keep], exps), np.hstack([tax_g[keep], vol_g[keep]]))
            pred = rs.basis(xi_val, exps) @ c
            study.append(
                [
                    m,
                    d,
                    int(keep.sum()),
                    taxel_errors(pred[:, : tax_g.shape[1]], tax_v).max(),
                    volume_errors(pred[:, tax_g.shape[1] :], vol_v).max(),
                ]
            )
    return degrees, loo_max, study


def run_reduce(
    scene: Scene,
    mesh_npz: str | Path,
    taxels_xyz: np.ndarray | None,
    out_dir: Path,
    progress: Callable[[str], None] | None = None,
) -> dict:
    """The reduce stage: build the scene's reduced model on mesh.npz for the taxels
    (T, 3) mm; write out_dir/reduced.npz and out_dir/validation.json. Returns the
    validation figures (a model past its bound is warned about through `progress`).
    Reads the scene here only: the model and the solver options (`fem.stage`) and
    `reduce_inputs`, handed to `reduce_to`."""
    from fruitcli.fem import io
    from fruitcli.fem.stage import build_model, solver_options

    if taxels_xyz is None:
        raise SceneError("[reduced]: no taxels to follow ([grid].taxels or make-tracks)")
    mesh = io.load_mesh(Path(mesh_npz))
    model = build_model(scene, mesh)
    inputs = reduce_inputs(scene)
    lo, hi = pressure_range(inputs.box, model.chamber_names)
    options = (
        solver_options(scene),
        solver_options(scene, first_state=True, jig=bool(model.jigs)),
    )
    return reduce_to(out_dir, model, mesh, taxels_xyz, lo, hi, inputs, options, progress)


def reduce_to(
    out_dir: Path,
    model: FemModel,
    mesh: dict,
    taxels_xyz: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    inputs: ReduceInputs,
    options: tuple[SolverOptions, SolverOptions],
    progress: Callable[[str], None] | None = None,
) -> dict:
    """The reduced model of `model` (on `mesh`, a loaded mesh.npz) over the pressure box
    [lo, hi] (K,) kPa for the taxels (T, 3) mm, with the sample counts of `inputs` and
    the solver options (of later states, of the first from rest): written to
    out_dir/reduced.npz and out_dir/validation.json; returns the validation figures."""
    from fruitcli.fem.elements import barycentric
    from fruitcli.fsutil import staged_dir

    progress = progress or _noop
    taxels = np.asarray(taxels_xyz, float).reshape(-1, 3)
    tet, w, outside = barycentric.locate(model.rest, model.tets, taxels)
    box = ", ".join(
        f"{c} {a:g}..{b:g}" for c, a, b in zip(model.chamber_names, lo, hi, strict=True)
    )
    progress(
        f"reduce: {inputs.points_per_axis}^{len(lo)} samples + {inputs.validation} "
        f"held-out full solves over {box} kPa"
    )
    extra = {
        "tets": model.tets,
        "elements": model.elements,
        "surface_tris": mesh["surface_tris"],
        "element": np.array(model.element_name),
        "material_model": np.array(model.material_name),
        "chamber_rest_volume_mm3": model.chamber_rest_volume_mm3,
        "taxel_outside": outside,
    }
    reduced = build(
        model,
        tet,
        w,
        lo,
        hi,
        options[0],
        options[1],
        points_per_axis=inputs.points_per_axis,
        max_degree=inputs.max_degree,
        validation=inputs.validation,
        seed=inputs.seed,
        surface_nodes=np.unique(mesh["surface_tris"]),
        extra=extra,
        progress=progress,
    )
    figures = reduced.validation()
    progress(reduced.describe())
    with staged_dir(out_dir) as tmp:
        reduced.save(tmp / "reduced.npz")
        _write_validation(tmp / "validation.json", figures, reduced, model.chamber_names, lo, hi)
    return figures


def _write_validation(
    path: Path,
    figures: dict,
    reduced: ReducedModel,
    names: list[str],
    lo: np.ndarray,
    hi: np.ndarray,
) -> None:
    """validation.json: the validation figures, the pressure box (kPa per chamber), the
    study rows (error against points per axis and degree) and the leave-one-out taxel
    error (mm) of each degree."""
    from fruitcli.fsutil import write_json

    study_keys = ("points_per_axis", "degree", "samples", "taxel_max_mm", "volume_max_pct")
    write_json(
        path,
        figures
        | {
            "range_kpa": {c: [float(a), float(b)] for c, a, b in zip(names, lo, hi, strict=True)},
            "study": [
                dict(zip(study_keys, row, strict=True)) for row in reduced.arrays["study"].tolist()
            ],
            "loo_taxel_max_mm": dict(
                zip(
                    map(str, reduced.arrays["loo_degrees"].tolist()),
                    reduced.arrays["loo_taxel_max_mm"].tolist(),
                    strict=True,
                )
            ),
        },
    )
