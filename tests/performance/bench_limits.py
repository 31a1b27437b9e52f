"""Benchmark: limit pressures (`fruitcli.fem.limits`).

1. The thick sphere's limit pressure (A = 10, B = 20 mm, E = 100 kPa, nu = 0.49, default
   element) on its octant at growing refinement: error against the incompressible
   closed form (0.8164 mu; the rest is compressibility) and against the compressible
   radial solution of the FEM's material (the discretization error), and the time.
2. `fruit limits` on the default Fruit (pipelines/fruit-breathing.toml: 3 chambers, one
   at a time and together along the breathing's ratios) with its wall time (skip with
   --no-fruit), and how far the breathing's largest pressure is from each limit. With
   --docs, its pv.csv and a summary (the limits, the time, date, commit and machine)
   go to docs/data/fruit-limits.{csv,json}, from which `make docs` draws the figure of
   docs/explanation/limits.md.
3. With --curves, instead of 2: each of the default Fruit's curves followed in this
   process (`fruitcli.fem.limits.follow` as `fruit limits` does: the body under its
   weight once, then each chamber's suction and inflation and the chambers together),
   each with its wall and CPU time and its samples; --mesh DIR keeps the mesh there.
4. With --stage, instead of 2: the planner's `limits` stage (`run_limits_stage`) on the
   default Fruit with every chamber at 20 kPa, near its limit, over --jobs worker
   processes (default: every core), timed; --mesh DIR as for --curves.

Run: .venv/bin/python tests/performance/bench_limits.py [--no-sphere] [--no-fruit]
[--out DIR] [--docs] [--jobs N] [--curves | --stage] [--mesh DIR]
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
MAX_RUNS = 1  # `make bench` runs it once: the default Fruit's curves take about 7 minutes
sys.path.insert(0, str(ROOT))  # tests.fem


def sphere_refinement() -> None:
    from fruitcli.fem import limits
    from tests.fem.meshing.test_mesh import octant_ball
    from tests.fem.test_limits import LIMIT_B_OVER_A_2, radial_pressure

    print("thick sphere B/A = 2, nu = 0.49, p2 octant: limit pressure by volume control")
    print("cells  layers  tets  limit/mu  err vs closed form  err vs radial  s")
    reference = None
    for cells in (1, 2, 3, 4):
        model = octant_ball(cells, cells, nu=0.49)
        mu, kappa = model.material.shear_modulus_kpa, model.material.bulk_modulus_kpa
        if reference is None:  # the radial solution's own peak
            from scipy.optimize import minimize_scalar

            top = minimize_scalar(
                lambda la, mu=mu, kappa=kappa: -radial_pressure(mu, kappa, la),
                bounds=(1.6, 2.0),
                method="bounded",
                options={"xatol": 1e-5},
            )
            reference = -top.fun
            print(f"radial solution's peak: {reference / mu:.5f} mu at la = {top.x:.4f}")
        t0 = time.perf_counter()
        curve = limits.follow(model, 0)
        dt = time.perf_counter() - t0
        p = curve.limit_pressure_kpa
        print(
            f"{cells:5d}  {cells:6d}  {len(model.conn):4d}  {p / mu:8.4f}  "
            f"{100 * (p / (LIMIT_B_OVER_A_2 * mu) - 1):+17.2f} %  "
            f"{100 * (p / reference - 1):+12.3f} %  {dt:5.1f}"
        )


def children_cpu() -> float:
    """CPU seconds (user + system, all threads) of the finished child processes."""
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def load_average() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def fruit_limits(out: Path, docs: bool = False, jobs: int | None = None) -> None:
    scene = ROOT / "pipelines" / "fruit-breathing.toml"
    t0, cpu0, load0 = time.perf_counter(), children_cpu(), load_average()
    fruit = Path(sys.executable).parent / "fruit"
    given = [] if jobs is None else ["--jobs", str(jobs)]
    code = subprocess.call(
        [str(fruit), "-q", "limits", str(scene), "--out", str(out), *given],
        cwd=ROOT,
        env=os.environ | {"MPLBACKEND": "Agg"},
    )
    wall, cpu, load = time.perf_counter() - t0, children_cpu() - cpu0, (load0, load_average())
    if code:
        print(f"fruit limits: exit {code}")
        return
    info = json.loads((out / "limits.json").read_text())
    print(
        f"\nfruit limits on the default Fruit ({info['element']}, {info['mesh']['elements']} "
        f"tets, --jobs {'default' if jobs is None else jobs}): {wall:.1f} s wall, {cpu:.1f} s "
        f"CPU (all threads and worker processes; make-tracks and tetra included), "
        f"{info['seconds']:.1f} s after the mesh; load average "
        f"{load[0]} -> {load[1]}"
    )
    import tomllib

    asked = tomllib.loads(scene.read_text())["actuation"]["pressure_kpa"]
    for name, ch in info["chambers"].items():
        lim, col = ch["limit_pressure_kpa"], ch["collapse_pressure_kpa"]
        top = max(asked.get(name, [0.0]))
        far = "" if lim is None else f", the breathing's {top:g} kPa is {100 * top / lim:.0f} %"
        print(
            f"  chamber {name}: limit {'none up to 27 V0' if lim is None else f'{lim:.4g} kPa'}"
            f"{far}; collapse {'none' if col is None else f'{col:.4g} kPa'}"
        )
    together = info.get("together")
    if together:
        lim = together["limit_pressure_kpa"]
        print(
            "  chambers together (ratios "
            + ", ".join(f"{c} {r:g}" for c, r in together["ratios"].items())
            + "): limit "
            + ("none up to 27 V0" if lim is None else f"{lim:.4g} kPa (largest chamber)")
        )
    if docs:
        write_docs(out, info, wall, asked, cpu, load, jobs)


def write_docs(
    out: Path, info: dict, wall: float, asked: dict, cpu: float, load, jobs: int | None
) -> None:
    """docs/data/fruit-limits.csv (the pv.csv) and fruit-limits.json (the limits, the
    breathing's largest pressures, the times (wall, CPU), load average before and after,
    date, commit and machine)."""
    import datetime
    import shutil

    sys.path.insert(0, str(HERE))
    from run_all import commit, processor

    version = commit()  # before the files below make the working tree differ
    data = ROOT / "docs" / "data"
    data.mkdir(exist_ok=True)
    shutil.copyfile(out / "pv.csv", data / "fruit-limits.csv")
    summary = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "commit": version,
        "machine": f"{processor()}, {os.cpu_count()} cores",
        "scene": "pipelines/fruit-breathing.toml",
        "wall_seconds": round(wall, 1),
        "cpu_seconds": round(cpu, 1),
        "jobs": jobs or os.cpu_count(),
        "load_average": list(load),
        "breathing_max_kpa": {c: max(v) for c, v in asked.items()},
        **info,
    }
    (data / "fruit-limits.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(f"wrote {data / 'fruit-limits.csv'} and fruit-limits.json")


def fruit_curves(mesh_dir: Path) -> None:
    """Each curve of `fruit limits` on the default Fruit, timed (wall and CPU)."""
    sys.path.insert(0, str(HERE))
    import numpy as np
    from bench_state import default_mesh

    from fruitcli.fem import curve_start, io, limits
    from fruitcli.fem.limits_stage import Curve, curve_options, follow_curve, scene_ratios
    from fruitcli.fem.stage import build_model, solver_options
    from fruitcli.scene import load_scene

    scene = load_scene(ROOT / "pipelines" / "fruit-breathing.toml", must_exist=False)
    model = build_model(scene, io.load_mesh(default_mesh(mesh_dir, scene)))
    options = curve_options(solver_options(scene))
    print(f"the default Fruit's curves, one by one; load average {load_average()}")
    t0, c0 = time.perf_counter(), time.process_time()
    start = curve_start.start_state(model, model.make_solver(options.linear_solver), options)
    print(
        f"  the body under its weight: {time.perf_counter() - t0:.1f} s wall, "
        f"{time.process_time() - c0:.1f} s CPU"
    )
    curves: list[tuple[str, int | np.ndarray, int]] = [
        (name, k, d) for k, name in enumerate(model.chamber_names) for d in (-1, 1)
    ]
    curves.append((limits.TOGETHER, scene_ratios(scene, model.chamber_names), 1))
    for name, k, d in curves:
        t1, c1 = time.perf_counter(), time.process_time()
        curve = follow_curve((model, Curve(k, d), options, start, None))
        value = curve.limit_pressure_kpa if d > 0 else curve.collapse_pressure_kpa
        print(
            f"  {name} {'inflation' if d > 0 else 'suction'}: {value} kPa ({curve.end}); "
            f"{len(curve.pressure_kpa) - 1} samples, {time.perf_counter() - t1:.1f} s wall, "
            f"{time.process_time() - c1:.1f} s CPU"
        )
    print(
        f"all: {time.perf_counter() - t0:.1f} s wall, {time.process_time() - c0:.1f} s CPU; "
        f"load average {load_average()}"
    )


def fruit_stage(mesh_dir: Path, jobs: int | None) -> None:
    """The planner's `limits` stage on the default Fruit with every chamber at
    NEAR_KPA (near its limit: each chamber's inflation and the chambers together
    followed on to their limits), timed (wall, and CPU of this process and its
    workers)."""
    import datetime
    import re

    sys.path.insert(0, str(HERE))
    from bench_state import default_mesh
    from run_all import commit, processor

    from fruitcli.fem.limits_stage import run_limits_stage
    from fruitcli.scene import load_scene, parse_scene
    from fruitcli.studies.parallel import CurveProcesses

    path = ROOT / "pipelines" / "fruit-breathing.toml"
    mesh = default_mesh(mesh_dir, load_scene(path, must_exist=False))
    pressures = ", ".join(f"c{k} = [{NEAR_KPA}]" for k in (1, 2, 3))
    text = re.sub(r"(?m)^pressure_kpa = .*$", f"pressure_kpa = {{ {pressures} }}", path.read_text())
    scene = parse_scene(text, path)
    load0, t0 = load_average(), time.perf_counter()
    cpu0 = time.process_time() + children_cpu()
    with tempfile.TemporaryDirectory() as out:
        info = run_limits_stage(scene, mesh, Path(out) / "limits", pool=CurveProcesses(jobs))
    wall, cpu = time.perf_counter() - t0, time.process_time() + children_cpu() - cpu0
    limits = ", ".join(f"{c} {v['limit_pressure_kpa']:.6g}" for c, v in info["chambers"].items())
    print(
        f"limits stage, default Fruit, every chamber at {NEAR_KPA:g} kPa, jobs "
        f"{'default' if jobs is None else jobs}: {wall:.1f} s wall, {cpu:.1f} s CPU; limits "
        f"{limits}, together {info['together']['limit_pressure_kpa']:.6g} kPa; "
        f"{datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC, commit {commit()[:12]}, "
        f"{processor()}, {os.cpu_count()} cores, load average {load0} -> {load_average()}"
    )


NEAR_KPA = 20.0
"""The chambers' pressure of `fruit_stage`: 0.58 of the material's shear modulus, over the
planner's NEAR_SHEAR_FRACTION, under every chamber's limit."""


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--no-sphere", action="store_true")
    parser.add_argument("--no-fruit", action="store_true")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--docs", action="store_true", help="write docs/data/fruit-limits.*")
    parser.add_argument("--curves", action="store_true", help="each curve timed in-process")
    parser.add_argument("--mesh", type=Path, default=None, help="keep the mesh in this folder")
    parser.add_argument("--jobs", type=int, default=None, help="fruit limits --jobs")
    parser.add_argument("--stage", action="store_true", help="the limits stage instead of 2")
    args = parser.parse_args()
    if not args.no_sphere:
        sphere_refinement()
    if args.stage:
        with tempfile.TemporaryDirectory() as tmp:
            mesh_dir = args.mesh or Path(tmp)
            mesh_dir.mkdir(parents=True, exist_ok=True)
            fruit_stage(mesh_dir, args.jobs)
    elif args.curves:
        with tempfile.TemporaryDirectory() as tmp:
            mesh_dir = args.mesh or Path(tmp)
            mesh_dir.mkdir(parents=True, exist_ok=True)
            fruit_curves(mesh_dir)
    elif not args.no_fruit:
        with tempfile.TemporaryDirectory() as tmp:
            fruit_limits(args.out or Path(tmp) / "limits", args.docs, args.jobs)


if __name__ == "__main__":
    main()
