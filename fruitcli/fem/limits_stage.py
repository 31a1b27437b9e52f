"""The limits stage: every chamber of a scene followed by volume control
(`fruitcli.fem.limits`), inflation and suction, on the scene's mesh and element.

`run_limits(scene, mesh_npz, out_dir)` -> out_dir/{limits.json, pv.csv, pv.png}:

- limits.json: chambers.<name>.{limit_pressure_kpa, limit_volume_growth_mm3,
  collapse_pressure_kpa, rest_volume_mm3, inflation_end, suction_end} (None where the
  range followed does not reach it); with several chambers, together.{ratios,
  limit_pressure_kpa, limit_volume_growth_mm3, inflation_end}: the chambers inflated
  together along the scene's own pressure ratios (each chamber's largest pressure over
  the states; equal ratios when the scene has none), the pressure the largest chamber's
  and the volume sum_k ratio_k V_k (None otherwise); element, mesh (nodes, elements),
  seconds;
- pv.csv: one row per sample (chamber, volume_growth_mm3, pressure_kpa), suction then
  inflation, by growing volume; the chambers together as chamber "together";
- pv.png: pressure against volume growth per chamber, the limit and collapse marked.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fruitcli.fem import curve_start, io, limits, pressure_check
from fruitcli.fem.curve_workers import CurvePool, curve_jobs, curve_label, run_curves
from fruitcli.fem.stage import build_model, solver_options, state_loads
from fruitcli.fsutil import atomic_path, staged_dir, write_csv, write_json

if TYPE_CHECKING:
    from fruitcli.fem.fem_model import FemModel
    from fruitcli.fem.linear_response import Start
    from fruitcli.fem.solver.options import SolverOptions
    from fruitcli.scene import Scene


def _noop(msg: str) -> None:
    pass


def _kpa(value: float | None) -> str:
    return "none in the range" if value is None else f"{value:.4g} kPa"


CURVE_FALL_STEPS = 1
"""Samples past the peak (or the lowest suction) that end a curve of `fruit limits`:
the parabola of the peak takes the top and its two neighbours either way, and a sample
past the peak of a flat chamber is its slowest (on the default Fruit, chamber c1's
second sample past its peak took 185 s of the curve's 420 s)."""


def curve_options(options: SolverOptions) -> SolverOptions:
    """The scene's [solver] options for the samples of a curve: Newton's tolerance
    loosened to `limits.CHECK_TOLERANCE`."""
    return replace(options, tolerance=max(options.tolerance, limits.CHECK_TOLERANCE))


@dataclass(frozen=True)
class Curve:
    """One curve of `fruit limits`: chamber `which` alone (an int) or the chambers along
    pressure ratios `which` (K,), inflated (direction 1) or sucked (-1)."""

    which: int | np.ndarray
    direction: int


def follow_curve(args: tuple) -> limits.ChamberCurve:
    """(model, Curve, options, start, progress) -> the curve followed on a fresh solver
    from `start` (`curve_start.start_state`) past its limit or collapse; module level, so a
    worker process can run it."""
    model, curve, options, start, progress = args
    return limits.follow(
        model,
        curve.which,
        curve.direction,
        fall_steps=CURVE_FALL_STEPS,
        halvings=limits.CURVE_HALVINGS if curve.direction > 0 else 0,
        options=options,
        progress=progress,
        start=start,
    )


def follow_curves(
    model: FemModel,
    curves: list[Curve],
    options: SolverOptions,
    start: Start,
    pool: CurvePool | None = None,
    progress: Callable[[str], None] = _noop,
) -> list[limits.ChamberCurve]:
    """Each of `curves` followed from `start` (`follow_curve`), in this process or over
    the worker processes of `pool` (`curve_workers.curve_jobs`): the curves share
    nothing but the start, so the results are those of one process. Inflations go
    first, the last given first (the chambers together: the longest); progress says
    each sample in one process, each curve in several."""
    n, why = curve_jobs(pool, len(curves), 3 * model.n_nodes)
    if pool is None or n == 1:
        return [follow_curve((model, c, options, start, progress)) for c in curves]
    order = sorted(range(len(curves)), key=lambda i: (-curves[i].direction, -i))
    cases = [(model, c, options, start, None) for c in curves]
    labels = [curve_label(model.chamber_names, c.which, c.direction) for c in curves]
    return run_curves(pool, follow_curve, cases, labels, order, n, why, progress)


def scene_ratios(scene: Scene, names: list[str]) -> np.ndarray:
    """(K,) the scene's own pressure ratios: each chamber's largest pressure over the
    states (0 where volume controlled or never inflated), scaled to a largest of 1;
    equal ratios when no chamber is inflated by pressure."""
    loads = state_loads(scene, names)
    top = np.zeros(len(names))
    for load in loads:
        p = np.where(load.volume_controlled, 0.0, load.pressure_kpa)
        top = np.maximum(top, p)
    return top / top.max() if top.max() > 0 else np.ones(len(names))


def _write_limits(
    out_dir: Path,
    model: FemModel,
    t0: float,
    chambers: dict,
    together: dict | None,
    rows: list,
    curves: list,
) -> dict:
    """Write limits.json (with the element, mesh and seconds since `t0`) and, when curves
    were followed, pv.csv from `rows` and pv.png from `curves` ((name, suction,
    inflation) each), all at once in out_dir.
    Returns the limits.json content."""
    info = {
        "chambers": chambers,
        "together": together,
        "element": model.element_name,
        "mesh": {"nodes": int(model.n_nodes), "elements": int(len(model.tets))},
        "seconds": round(time.perf_counter() - t0, 2),
    }
    with staged_dir(out_dir) as tmp:
        if curves:
            write_csv(tmp / "pv.csv", ["chamber", "volume_growth_mm3", "pressure_kpa"], rows)
            plot_curves(tmp / "pv.png", curves)
        write_json(tmp / pressure_check.LIMITS_FILE, info)
    return info


def run_limits(
    scene: Scene,
    mesh_npz: str | Path,
    out_dir: Path,
    progress: Callable[[str], None] | None = None,
    pool: CurvePool | None = None,
) -> dict:
    """Follow each chamber's curve, over the worker processes of `pool` (None: in this
    process, `follow_curves`); write limits.json, pv.csv and pv.png (see module
    docstring). Returns the limits.json content."""
    progress = progress or _noop
    t0 = time.perf_counter()
    model = build_model(scene, io.load_mesh(Path(mesh_npz)))
    options = curve_options(solver_options(scene))
    solver = model.make_solver(options.linear_solver)
    start = curve_start.start_state(model, solver, options, progress)
    names = model.chamber_names
    order = [Curve(k, d) for k in range(len(names)) for d in (-1, 1)]
    ratio = scene_ratios(scene, names)
    if len(names) > 1:
        order.append(Curve(ratio, 1))
    followed = follow_curves(model, order, options, start, pool, progress)
    chambers, rows, curves = {}, [], []
    for k, name in enumerate(names):
        down, up = followed[2 * k], followed[2 * k + 1]
        curves.append((name, down, up))
        chambers[name] = {
            "limit_pressure_kpa": up.limit_pressure_kpa,
            "limit_volume_growth_mm3": up.limit_growth_mm3,
            "collapse_pressure_kpa": down.collapse_pressure_kpa,
            "rest_volume_mm3": up.rest_volume_mm3,
            "inflation_end": up.end,
            "suction_end": down.end,
        }
        samples = list(zip(down.growth_mm3[:0:-1], down.pressure_kpa[:0:-1], strict=True))
        samples += list(zip(up.growth_mm3, up.pressure_kpa, strict=True))
        rows += [(name, g, p) for g, p in samples]
        progress(
            f"limits: chamber {name}: limit pressure {_kpa(up.limit_pressure_kpa)}, "
            f"collapse {_kpa(down.collapse_pressure_kpa)}"
        )
    together = None
    if len(names) > 1:
        up = followed[-1]
        together = {
            "ratios": dict(zip(names, map(float, ratio), strict=True)),
            "limit_pressure_kpa": up.limit_pressure_kpa,
            "limit_volume_growth_mm3": up.limit_growth_mm3,
            "inflation_end": up.end,
        }
        rows += [
            (limits.TOGETHER, g, p) for g, p in zip(up.growth_mm3, up.pressure_kpa, strict=True)
        ]
        curves.append((limits.TOGETHER, limits.ChamberCurve(limits.TOGETHER, 0.0), up))
        progress(f"limits: chambers together: limit pressure {_kpa(up.limit_pressure_kpa)}")
    return _write_limits(out_dir, model, t0, chambers, together, rows, curves)


def plot_curves(
    path: Path, curves: list[tuple[str, limits.ChamberCurve, limits.ChamberCurve]]
) -> None:
    """pv.png: pressure (kPa) against volume growth (mm^3), one line per chamber, the
    limit (triangle) and collapse (cross) marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for name, down, up in curves:
        g = down.growth_mm3[:0:-1] + up.growth_mm3
        p = down.pressure_kpa[:0:-1] + up.pressure_kpa
        label, style = f"chamber {name}", ".-"
        if name == limits.TOGETHER:
            label, style = "together (largest chamber's pressure)", ".--"
        (line,) = ax.plot(g, p, style, label=label)
        # set together (`limits`)
        if up.limit_pressure_kpa is not None and up.limit_growth_mm3 is not None:
            ax.plot(
                [up.limit_growth_mm3], [up.limit_pressure_kpa], "^", ms=10, color=line.get_color()
            )
            ax.annotate(
                f"limit {up.limit_pressure_kpa:.4g} kPa",
                (up.limit_growth_mm3, up.limit_pressure_kpa),
                textcoords="offset points",
                xytext=(0, -22),
                ha="center",
            )
        if down.collapse_pressure_kpa is not None:
            i = int(np.argmin(np.abs(np.array(down.pressure_kpa) - down.collapse_pressure_kpa)))
            ax.plot(
                [down.growth_mm3[i]],
                [down.collapse_pressure_kpa],
                "x",
                ms=10,
                color=line.get_color(),
            )
            ax.annotate(
                f"collapse {down.collapse_pressure_kpa:.4g} kPa",
                (down.growth_mm3[i], down.collapse_pressure_kpa),
                textcoords="offset points",
                xytext=(10, -4),
            )
    ax.axhline(0.0, color="0.7", lw=0.8)
    ax.axvline(0.0, color="0.7", lw=0.8)
    ax.set_xlabel("chamber volume growth (mm³)")
    ax.set_ylabel("chamber pressure (kPa)")
    ax.set_title("Pressure against volume (volume control)")
    ax.margins(x=0.05, y=0.12)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, format="png")
    plt.close(fig)


NEAR_SHEAR_FRACTION = 0.5
"""The planner's `limits` stage runs when a chamber's largest pressure magnitude
reaches this fraction of the material's shear modulus: the incompressible neo-Hookean
sphere's limit pressure is 0.49 mu when its wall is half its cavity radius thick (B/A
= 1.5), 0.82 mu at B/A = 2. Below it `simulate` checks the pressures itself (its
compliance screen, `pressure_check.SCREEN_GROWTH`); the default Fruit's breathing (12 kPa,
0.36 mu) stays below."""


def near_limit(scene: Scene) -> tuple[bool, str]:
    """(whether the scene's pressures come near a limit by the cheap estimate
    NEAR_SHEAR_FRACTION, why), from the scene alone (no mesh)."""
    from fruitcli.fem.materials import build as materials

    table = scene.actuation.pressure_kpa or {}
    if not scene.chambers or not table:
        return False, "no chamber pressures"
    top = max(max(abs(v) for v in values) for values in table.values())
    mu = materials.from_scene(scene.material).shear_modulus_kpa
    if top < NEAR_SHEAR_FRACTION * mu:
        return False, (
            f"pressures up to {top:g} kPa, under {NEAR_SHEAR_FRACTION:g} mu = "
            f"{NEAR_SHEAR_FRACTION * mu:.3g} kPa: simulate checks them itself"
        )
    return True, (
        f"pressures up to {top:g} kPa, {top / mu:.2g} mu: near a chamber's limit "
        "pressure, checked against it once"
    )


def run_limits_stage(
    scene: Scene,
    mesh_npz: str | Path,
    out_dir: Path,
    progress: Callable[[str], None] | None = None,
    pool: CurvePool | None = None,
) -> dict:
    """The planner's `limits` stage: the scene's pressures checked against the limits
    (`pressure_check.check_pressures` on the scene's states, without its screen: the planner
    runs this stage when the pressures come near a limit, `near_limit`), each
    pressurised chamber's curve followed on to its limit or collapse (over the worker
    processes of `pool`, `curve_workers.curve_jobs`); raises the
    check's one line for a pressure past one, else writes out_dir/limits.json
    (chambers.<name>.{followed, limit_pressure_kpa, limit_volume_growth_mm3,
    collapse_pressure_kpa}, together (or None), element, mesh, seconds) and, when a
    curve was followed, pv.csv and pv.png. `simulate` then skips its own check
    (`pressure_check.checked_by`)."""
    progress = progress or _noop
    t0 = time.perf_counter()
    model = build_model(scene, io.load_mesh(Path(mesh_npz)))
    names = model.chamber_names
    loads = state_loads(scene, names)
    pressure_check.check_growth(model, loads)
    asked = np.array([np.where(ld.volume_controlled, np.nan, ld.pressure_kpa) for ld in loads])
    keys = pressure_check.pressure_keys(names)
    found: list = []
    solver = model.make_solver(scene.solver.linear_solver)
    pressure_check.check_pressures(
        model,
        asked,
        keys,
        solver,
        solver_options(scene),
        progress,
        screen=0.0,
        found=found,
        pool=pool,
    )
    chambers: dict[str, dict[str, Any]] = {
        c: {
            "followed": [],
            "limit_pressure_kpa": None,
            "limit_volume_growth_mm3": None,
            "collapse_pressure_kpa": None,
        }
        for c in names
    }
    together: dict[str, Any] | None = None
    rows: list[tuple[str, float, float]] = []
    by_name: dict[str, tuple[limits.ChamberCurve, limits.ChamberCurve]] = {}
    for direction, curve in found:
        samples = list(zip(curve.growth_mm3[1:], curve.pressure_kpa[1:], strict=True))
        rows += [(curve.name, g, p) for g, p in samples]
        down, up = by_name.get(curve.name, (limits.ChamberCurve(curve.name, 0.0),) * 2)
        by_name[curve.name] = (curve, up) if direction < 0 else (down, curve)
        entry: dict[str, Any] = {
            "followed": [],
            "limit_pressure_kpa": curve.limit_pressure_kpa,
            "limit_volume_growth_mm3": curve.limit_growth_mm3,
        }
        if curve.name == limits.TOGETHER:
            together = entry
            continue
        entry = chambers[curve.name]
        entry["followed"].append("inflation" if direction > 0 else "suction")
        if direction > 0:
            entry["limit_pressure_kpa"] = curve.limit_pressure_kpa
            entry["limit_volume_growth_mm3"] = curve.limit_growth_mm3
        else:
            entry["collapse_pressure_kpa"] = curve.collapse_pressure_kpa
    if found:
        rows = sorted([(c, 0.0, 0.0) for c in by_name] + rows, key=lambda r: (r[0], r[1]))
    curves = [(c, d, u) for c, (d, u) in by_name.items()]
    info = _write_limits(out_dir, model, t0, chambers, together, rows, curves)
    progress(
        "limits: "
        + (f"{len(found)} curve(s) followed" if found else "no pressure near a limit")
        + f" ({info['seconds']:.1f} s)"
    )
    return info
