"""Error against run time: what each accuracy/time knob costs and buys.

Knobs: FEM mesh size, Newton tolerance and iteration cap, linear solver, detection
variant. Figures per setting: time per FEM state (median ms), time per frame (us), the
taxels' position error in the last (most deformed) state against the finest setting's
(mean and max, mm), and the localization error on the bench (mean, mm).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict

import numpy as np

from fruitcli.scene import load_scene

if TYPE_CHECKING:
    from fruitcli.scene import Scene
    from fruitcli.sensing.inputs_stage import LocateInputs


@dataclass(frozen=True)
class FemCase:
    """One FEM setting: mesh size (mm), Newton tolerance, iteration cap, linear solver,
    element, material and displacement tolerance (mm; None: the scene's)."""

    name: str
    size_mm: float
    tolerance: float
    max_iterations: int
    linear_solver: str
    element: str | None = None
    material: str | None = None
    displacement_tolerance_mm: float | None = None


def fem_cases(default_size: float) -> list[FemCase]:
    sizes = sorted({round(default_size * f, 2) for f in (2.0, 1.5, 1.25, 1.0, 0.8)}, reverse=True)
    cases = [FemCase(f"size {s:g} mm", s, 1e-6, 25, "pcg") for s in sizes]
    # the residual tolerance alone (the displacement tolerance would stop the tight ones)
    cases += [
        FemCase(
            f"tol {t:g}, residual alone", default_size, t, 25, "pcg", displacement_tolerance_mm=0.0
        )
        for t in (1e-2, 1e-4, 1e-6, 1e-8)
    ]
    cases += [
        FemCase(
            "tol 1e-3, cap 3 its, residual alone",
            default_size,
            1e-3,
            3,
            "pcg",
            displacement_tolerance_mm=0.0,
        ),
        FemCase("solver direct", default_size, 1e-6, 25, "direct"),
    ]
    cases += [
        FemCase(
            "element p1, corotational (the paper's model)",
            default_size,
            1e-6,
            25,
            "pcg",
            "p1",
            "corotational",
        ),
        FemCase("element p1, neo-hookean", default_size, 1e-6, 25, "pcg", "p1", "neo-hookean"),
        FemCase(
            "element p2-pure, neo-hookean", default_size, 1e-6, 25, "pcg", "p2-pure", "neo-hookean"
        ),
    ]
    return cases


def _scene_variant(scene: Scene, case: FemCase):
    changes = {
        "mesh.size_mm": case.size_mm,
        "solver.tolerance": case.tolerance,
        "solver.max_iterations": case.max_iterations,
        "solver.linear_solver": case.linear_solver,
    }
    if case.displacement_tolerance_mm is not None:
        changes["solver.displacement_tolerance_mm"] = case.displacement_tolerance_mm
    if case.element is not None:
        changes |= {"fem.element": case.element, "material.model": case.material}
    return scene.with_values(changes)


def run_fem_case(args: tuple[Path, Path, Path | None, Path, FemCase]) -> dict:
    """Mesh (cached per size) and simulate one setting; returns timings and taxels."""
    from fruitcli.errors import FruitError
    from fruitcli.fem.stage import run_simulate, run_tetra
    from fruitcli.tables import read_taxels

    scene_path, work, solid, taxels_csv, case = args
    scene = _scene_variant(load_scene(scene_path), case)
    row = {
        "setting": case.name,
        "size_mm": case.size_mm,
        "tolerance": case.tolerance,
        "max_iterations": case.max_iterations,
        "linear_solver": case.linear_solver,
    }
    mesh_dir = Path(work) / f"mesh-{case.size_mm:g}"
    try:
        if not (mesh_dir / "mesh.npz").exists():
            run_tetra(scene, solid, mesh_dir)
        out = Path(work) / ("sim-" + case.name.replace(" ", "_").replace("(", "").replace(")", ""))
        xyz = read_taxels(taxels_csv).xyz_mm
        t0 = time.perf_counter()
        run_simulate(scene, mesh_dir / "mesh.npz", xyz, out)
        wall = time.perf_counter() - t0
        with np.load(out / "states.npz", allow_pickle=False) as st:
            row.update(
                tets=int(len(st["tets"])),
                state_ms=float(np.median(st["solve_ms"])),
                iterations=float(np.mean(st["iterations"])),
                residual=float(np.max(st["residual"])),
                simulate_s=wall,
                taxels=st["taxels_mm"][-1].tolist(),
            )
        row["status"] = "ok"
    except FruitError as exc:
        row["status"] = f"failed: {exc}"
    return row


def add_errors(rows: list[dict]) -> None:
    """Taxel error of each row's last state against the finest converged setting."""
    ok = [r for r in rows if r["status"] == "ok"]
    if not ok:
        return
    ref = min(ok, key=lambda r: (r["size_mm"], r["tolerance"], "element" in r["setting"]))
    ref_xyz = np.asarray(ref["taxels"])
    for r in ok:
        d = np.linalg.norm(np.asarray(r["taxels"]) - ref_xyz, axis=1)
        r["taxel_err_mean_mm"] = float(d.mean())
        r["taxel_err_max_mm"] = float(d.max())
    for r in rows:
        r.pop("taxels", None)
    for r in rows:
        r["reference"] = r is ref


def pareto(points: list[tuple[float, float]]) -> list[bool]:
    """True for points no other point beats in both coordinates (both minimized)."""
    flags = []
    for i, (a, b) in enumerate(points):
        dominated = any(
            (c <= a and d <= b) and (c < a or d < b) for j, (c, d) in enumerate(points) if j != i
        )
        flags.append(not dominated)
    return flags


PRINTER_ACCURACY_MM = 0.1  # the paper's bench positions to 0.1 mm (Sec. V-B)
PLOT_FLOOR_MM = 1e-4  # where the log plot draws an error of 0 (the reference setting)


def default_reason(rows: list[dict], default_name: str) -> str:
    """What the measured rows say about the default setting: its taxel error against the
    bench printer's accuracy, and what the reference (finest) setting would cost."""
    row = next((r for r in rows if r["setting"] == default_name and r["status"] == "ok"), None)
    if row is None:
        return f"The default setting ({default_name}) did not run."
    err, ms = row["taxel_err_mean_mm"], row["state_ms"]
    head = (
        f"Default ({default_name}, the scene's tolerances, pcg): mean taxel error "
        f"{err:.3f} mm against the finest setting, at {ms:.0f} ms per state"
    )
    if err < PRINTER_ACCURACY_MM:
        return (
            f"{head}: below the bench's {PRINTER_ACCURACY_MM} mm positioning accuracy, "
            "so finer settings cost time for no difference the bench can measure."
        )
    ref = next((r for r in rows if r.get("reference")), None)
    cost = (
        f"; the finest setting ({ref['setting']}) takes {ref['state_ms']:.0f} ms per state"
        if ref is not None
        else ""
    )
    return (
        f"{head}: above the bench's {PRINTER_ACCURACY_MM} mm positioning accuracy{cost}. "
        "Whether that matters depends on the localization error, which is mm-sized for "
        "N9 on the bench (see the detection table of a scene with a bench)."
    )


class DetectionChange(TypedDict, total=False):
    """A detection variant's [detection] keys; the others stay as the scene gives them."""

    method: str
    noise_floor_counts: float


DETECTION_VARIANTS: dict[str, DetectionChange] = {
    "n9 (paper)": {"method": "n9"},
    "n9 + noise floor 6": {"method": "n9_floor", "noise_floor_counts": 6.0},
    "peaks": {"method": "peaks"},
}


def run_detection_variants(
    base: LocateInputs, bench_dir: Path, taxels_csv: Path, states: Path | None, work: Path
) -> list[dict]:
    """Locate the bench frames with each detection variant of the scene's locate inputs
    `base`; error and time per frame."""
    from fruitcli.evaluation.report import evaluate_pair
    from fruitcli.sensing.stages import LocateFiles, run_locate

    rows = []
    for name, change in DETECTION_VARIANTS.items():
        variant = replace(base, settings=replace(base.settings, **change))
        errs, frames, seconds = [], 0, 0.0
        for ind_dir in sorted(p for p in bench_dir.iterdir() if (p / "frames.npz").exists()):
            out = work / "detect" / name.split()[0] / ind_dir.name
            t0 = time.perf_counter()
            files = LocateFiles(ind_dir / "frames.npz", taxels_csv, states, out)
            summary = run_locate(variant, files)
            seconds += time.perf_counter() - t0
            with np.load(ind_dir / "frames.npz", allow_pickle=False) as f:
                frames += len(f["frames"])
            s, *_ = evaluate_pair(ind_dir / "truth.csv", out / "measured.csv", label=ind_dir.name)
            errs.append(s["mean_mm"])
            del summary
        rows.append(
            {
                "variant": name,
                "loc_err_mean_mm": float(np.mean(errs)),
                "us_per_frame": 1e6 * seconds / max(frames, 1),
                "frames": frames,
            }
        )
    return rows


def write_outputs(out: Path, fem_rows: list[dict], det_rows: list[dict], default_name: str) -> None:
    """runtime.md, runtime.json and runtime.png (time per state against taxel error)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fruitcli.fsutil import atomic_path, write_json, write_text

    ok = [r for r in fem_rows if r["status"] == "ok"]
    front = pareto([(r["state_ms"], r["taxel_err_mean_mm"]) for r in ok])
    for r, f in zip(ok, front, strict=True):
        r["pareto"] = f
    lines = [
        "# Error against run time",
        "",
        "| setting | tets | ms per state | Newton its | taxel error mean / max (mm) | Pareto |",
        "|---|---|---|---|---|---|",
    ]
    for r in fem_rows:
        if r["status"] != "ok":
            lines.append(f"| {r['setting']} | - | - | - | {r['status']} | |")
            continue
        mark = "yes" if r.get("pareto") else ""
        name = r["setting"] + (" (default)" if r["setting"] == default_name else "")
        lines.append(
            f"| {name} | {r['tets']} | {r['state_ms']:.1f} | "
            f"{r['iterations']:.1f} | {r['taxel_err_mean_mm']:.3f} / "
            f"{r['taxel_err_max_mm']:.3f} | {mark} |"
        )
    lines += [
        "",
        "Taxel error: positions in the last state against the finest setting "
        "(smallest mesh, tightest tolerance). Time per state: the median over the "
        "scene's states, each solved from the previous one (the first from rest).",
        "",
        default_reason(fem_rows, default_name),
        "",
    ]
    if det_rows:
        lines += ["| detection | localization error mean (mm) | us per frame |", "|---|---|---|"]
        lines += [
            f"| {r['variant']} | {r['loc_err_mean_mm']:.2f} | {r['us_per_frame']:.1f} |"
            for r in det_rows
        ]
    else:
        lines.append("No detection variants: the scene has no [bench].")
    write_text(out / "runtime.md", "\n".join(lines) + "\n")
    write_json(out / "runtime.json", {"fem": fem_rows, "detection": det_rows})
    fig, ax = plt.subplots(figsize=(10, 4.8))
    placed: list[tuple[float, float]] = []  # label anchors, log10 (ms, mm)
    key = []
    for i, r in enumerate(sorted(ok, key=lambda r: (-r["taxel_err_mean_mm"], r["state_ms"])), 1):
        color = "tab:red" if r.get("pareto") else "tab:blue"
        xy = (r["state_ms"], max(r["taxel_err_mean_mm"], PLOT_FLOOR_MM))
        ax.scatter(*xy, color=color)
        lx, ly = np.log10(xy)
        # each point carries a number (its setting in the key beside the axes); numbers
        # of nearby points are stacked downwards instead of printed over each other
        near = sum(abs(lx - px) < 0.25 and abs(ly - py) < 0.15 for px, py in placed)
        placed.append((lx, ly))
        ax.annotate(
            str(i),
            xy,
            fontsize=8,
            color=color,
            xytext=(5, 3 - 10 * near),
            textcoords="offset points",
            arrowprops={"arrowstyle": "-", "color": "0.6", "lw": 0.5} if near else None,
        )
        zero = (
            f" (the reference: error 0, drawn at {PLOT_FLOOR_MM:g})"
            if r["taxel_err_mean_mm"] == 0
            else ""
        )
        key.append(f"{i:2d}  {r['setting']}{zero}")
    ax.text(
        1.03, 1.0, "\n".join(key), transform=ax.transAxes, fontsize=8, va="top", family="monospace"
    )
    pts = sorted(
        (r["state_ms"], max(r["taxel_err_mean_mm"], PLOT_FLOOR_MM)) for r in ok if r.get("pareto")
    )
    if pts:
        ax.plot(*zip(*pts, strict=True), color="tab:red", lw=1, label="Pareto front")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("time per FEM state (ms)")
    ax.set_ylabel("taxel position error, mean (mm)")
    ax.grid(True, which="both", color="0.85")
    ax.legend(loc="lower left")
    fig.tight_layout()
    fig.subplots_adjust(right=0.55)
    with atomic_path(out / "runtime.png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
