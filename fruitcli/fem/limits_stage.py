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
from pathlib import Path

import numpy as np

from fruitcli.fem import io, limits
from fruitcli.fem.stage import build_model, element_name, solver_options, state_loads
from fruitcli.fsutil import atomic_path, staged_dir, write_csv, write_json


def _noop(msg: str) -> None:
    pass


def _kpa(value: float | None) -> str:
    return "none in the range" if value is None else f"{value:.4g} kPa"


def follow_both(model, k: int, options, progress=_noop) -> tuple:
    """(suction curve, inflation curve) of chamber k, each on a fresh solver."""
    down = limits.follow(model, k, -1, options=options, progress=progress)
    up = limits.follow(model, k, 1, options=options, progress=progress)
    return down, up


def scene_ratios(scene, names: list[str]) -> np.ndarray:
    """(K,) the scene's own pressure ratios: each chamber's largest pressure over the
    states (0 where volume controlled or never inflated), scaled to a largest of 1;
    equal ratios when no chamber is inflated by pressure."""
    loads = state_loads(scene, names)
    top = np.zeros(len(names))
    for load in loads:
        p = np.where(load.volume_controlled, 0.0, load.pressure_kpa)
        top = np.maximum(top, p)
    return top / top.max() if top.max() > 0 else np.ones(len(names))


def run_limits(scene, mesh_npz, out_dir, progress=None) -> dict:
    """Follow each chamber's curve; write limits.json, pv.csv and pv.png (see module
    docstring). Returns the limits.json content."""
    progress = progress or _noop
    t0 = time.perf_counter()
    model = build_model(scene, io.load_mesh(Path(mesh_npz)))
    options = solver_options(scene)
    chambers, rows, curves = {}, [], []
    for k, name in enumerate(model.chamber_names):
        down, up = follow_both(model, k, options, progress)
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
    if len(model.chamber_names) > 1:
        ratio = scene_ratios(scene, model.chamber_names)
        up = limits.follow(model, ratio, 1, options=options, progress=progress)
        together = {
            "ratios": dict(zip(model.chamber_names, map(float, ratio), strict=True)),
            "limit_pressure_kpa": up.limit_pressure_kpa,
            "limit_volume_growth_mm3": up.limit_growth_mm3,
            "inflation_end": up.end,
        }
        samples = zip(up.growth_mm3, up.pressure_kpa, strict=True)
        rows += [(limits.TOGETHER, g, p) for g, p in samples]
        curves.append((limits.TOGETHER, limits.ChamberCurve(limits.TOGETHER, 0.0), up))
        progress(f"limits: chambers together: limit pressure {_kpa(up.limit_pressure_kpa)}")
    info = {
        "chambers": chambers,
        "together": together,
        "element": element_name(model),
        "mesh": {"nodes": int(model.n_nodes), "elements": int(len(model.tets))},
        "seconds": round(time.perf_counter() - t0, 2),
    }
    with staged_dir(out_dir) as tmp:
        write_csv(tmp / "pv.csv", ["chamber", "volume_growth_mm3", "pressure_kpa"], rows)
        plot_curves(tmp / "pv.png", curves)
        write_json(tmp / "limits.json", info)
    return info


def plot_curves(path, curves) -> None:
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
        if up.limit_pressure_kpa is not None:
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
