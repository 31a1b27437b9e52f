"""Benchmark: a quadratic state from the previous one on the default Fruit
(pipelines/fruit-breathing.toml as it stands: p2, neo-Hookean, 3 chambers).

Two load paths, each solved in order with one solver (as `fruit simulate`): the scene's
breathing states (the first from rest, then each from the previous one), and a pressure
sweep of chamber c1 from 0 to the breathing's largest c1 pressure in --sweep equal steps
with the other chambers at 0. Prints, per path, the median wall time of a state from the
previous one and its CPU time (all threads; less sensitive to other users' load than
the wall time), the state from rest, Newton steps, CG iterations and factorizations, and
where the solver's time went (assembly: the solver's tangent updates, which do not
include a load step's first element tangents, evaluated with the forces at Newton's
start; factorizations), each figure stamped with the
date, commit, machine and the load average before and after (the machine may be shared:
compare figures taken at a like load). --repeat N runs each path N times (fresh solver
each time) and prints every run's median; each path's line also has, per state, the kept
factor's solves and Newton's force evaluations with their mean times (`WorkCounter`,
which wraps the two methods while the path runs); --mesh DIR keeps the tetrahedral mesh there
(built once, about a minute) so that later runs skip the meshing.

--solver-threads N runs MKL PARDISO on N threads (`fruit --solver-threads`; the results
then vary between runs within the solver's tolerances).

--save PREFIX writes each path's states (nodes, mm) to PREFIX-breathing.npz and
PREFIX-sweep.npz, to compare the equilibria of two versions.

--first times only the breathing's first state, from rest, as `fruit simulate` solves it
(`run_simulate` with the first state's pressures: the pressure check's compliance at
rest, which makes the first factorization, then the state), --repeat N times: each time
into a new output folder, then again into the same folder (a later run on the same
body, which takes the first state kept there, `sample_cache.kept_first_state`). Prints
the state's wall time, Newton steps, factorizations and CG iterations and the whole
call's wall time (the model, the check, the state and the files); with --save, the
state's nodes to PREFIX-first.npz.

Run: .venv/bin/python tests/performance/bench_state.py [--mesh DIR] [--repeat N]
     [--sweep 10] [--only breathing|sweep] [--save PREFIX] [--first] [--solver-threads N]
"""

import argparse
import os
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))


def load_text() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def default_mesh(mesh_dir: Path, scene) -> Path:
    """The default Fruit's tetrahedral mesh (mesh.npz) in mesh_dir, built when missing."""
    from bench_fem import fruit_solid

    from fruitcli.fem.stage import run_tetra

    npz = mesh_dir / "mesh.npz"
    if not npz.exists():
        run_tetra(scene, fruit_solid(mesh_dir), mesh_dir)
    return npz


class WorkCounter:
    """Counts and times, while active, the kept factor's solves (PARDISO's, one per
    right-hand side) and Newton's evaluations of the forces at an iterate (with the
    element tangents at a load step's start), by wrapping the two methods; the library
    itself is not changed. `totals()` -> {name: [calls, seconds]}."""

    def __init__(self) -> None:
        from fruitcli.fem.solver import newton, pardiso

        self.targets = [(pardiso.Pardiso, "solve"), (newton.NewtonStep, "evaluate")]
        self.counts = {"solve": [0, 0.0], "evaluate": [0, 0.0]}

    def __enter__(self) -> "WorkCounter":
        self.saved = [(cls, name, getattr(cls, name)) for cls, name in self.targets]
        for cls, name, fn in self.saved:
            setattr(cls, name, self._wrapped(name, fn))
        return self

    def __exit__(self, *exc) -> None:
        for cls, name, fn in self.saved:
            setattr(cls, name, fn)

    def _wrapped(self, name, fn):
        counts = self.counts[name]

        def call(obj, *args, **kwargs):
            t0 = time.perf_counter()
            out = fn(obj, *args, **kwargs)
            counts[1] += time.perf_counter() - t0
            wide = name == "solve" and args and args[0].ndim == 2
            counts[0] += args[0].shape[1] if wide else 1
            return out

        return call

    def totals(self) -> dict[str, list]:
        return {k: list(v) for k, v in self.counts.items()}


def run_path(scene, mesh_npz: Path, loads_of) -> dict:
    """Solve the loads (a function of the chamber names) in order with one solver."""
    from fruitcli.fem import io
    from fruitcli.fem.stage import build_model, solver_options

    model = build_model(scene, io.load_mesh(mesh_npz))
    loads = loads_of(model.chamber_names)
    solver = model.make_solver(solver_options(scene).linear_solver)
    with WorkCounter() as work:
        return _solve_path(scene, model, loads, solver, work)


def _solve_path(scene, model, loads, solver, work: WorkCounter) -> dict:
    """`run_path`'s states, counting their solves and evaluations from the second on."""
    from fruitcli.fem.solver.state import solve_state
    from fruitcli.fem.stage import solver_options

    x = p = prev = None
    ms, cpu, its, states = [], [], [], []
    stats0 = work0 = None
    for i, load in enumerate(loads):
        opts = solver_options(scene, first_state=i == 0)
        cpu0 = time.process_time()
        res = solve_state(
            model, load, x_start=x, load_start=prev, pressure_start=p, options=opts, solver=solver
        )
        if stats0 is None:
            stats0, work0 = dict(solver.stats), work.totals()
        ms.append(res.solve_ms)
        cpu.append(1e3 * (time.process_time() - cpu0))
        its.append(res.iterations)
        states.append(res)
        x, p, prev = res.x, res.pressure_kpa, load
    assert stats0 is not None and work0 is not None  # set after the first state
    later = {k: solver.stats[k] - stats0[k] for k in solver.stats}
    now = work.totals()
    later_work = {k: [now[k][0] - work0[k][0], now[k][1] - work0[k][1]] for k in now}
    return {
        "model": model,
        "ms": np.array(ms),
        "cpu_ms": np.array(cpu),
        "iterations": np.array(its),
        "later_stats": later,
        "later_work": later_work,
        "states": states,
    }


def _work_text(work: dict[str, list], states: int) -> str:
    """Per state: the kept factor's solves and the forces' evaluations, each with its
    mean time (`WorkCounter`)."""
    parts = []
    for name, what in (("solve", "factor solves"), ("evaluate", "force evaluations")):
        calls, seconds = work[name]
        each = 1e3 * seconds / calls if calls else 0.0
        parts.append(f"{calls / states:.1f} {what} of {each:.1f} ms")
    return "per state " + ", ".join(parts)


def first_state(scene, mesh_npz: Path, out: Path) -> dict:
    """`run_simulate` of the breathing's first state alone into `out`: the state's
    figures and the call's wall time (s)."""
    from fruitcli.fem.stage import run_simulate, state_loads

    names = [c.name for c in scene.chambers]
    first = state_loads(scene, names)[0].pressure_kpa
    t0 = time.perf_counter()
    info = run_simulate(
        scene, mesh_npz, None, out, pressures={n: [first[k]] for k, n in enumerate(names)}
    )
    wall = time.perf_counter() - t0
    with np.load(out / "states.npz", allow_pickle=False) as st:
        x = st["rest_nodes"] + st["displacement_mm"][0]
    return info | {"wall_s": wall, "x": x}


def run_first(scene, npz: Path, args) -> None:
    """--first: the first state from rest in a new folder, then again in the same one."""
    for _ in range(args.repeat):
        with tempfile.TemporaryDirectory() as out_dir:
            for run in ("new folder", "same folder"):
                before = load_text()
                r = first_state(scene, npz, Path(out_dir))
                st = r["linear_solver"]
                print(
                    f"first state from rest, {run}: {r['solve_ms'][0]:.0f} ms, "
                    f"{r['iterations'][0]} Newton steps; {st['factorizations']} "
                    f"factorizations and {st['cg_iterations']} CG iterations in the call "
                    f"(the check's included), the call {r['wall_s']:.1f} s; load average "
                    f"{before} -> {load_text()}",
                    flush=True,
                )
                if args.save is not None and run == "new folder":
                    np.savez(f"{args.save}-first.npz", x=r["x"])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--mesh", type=Path, default=None, help="keep the mesh in this folder")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--sweep", type=int, default=10, help="steps of the c1 pressure sweep")
    ap.add_argument("--only", choices=("breathing", "sweep"), default=None)
    ap.add_argument(
        "--first", action="store_true", help="time only the first state, as fruit simulate"
    )
    ap.add_argument(
        "--save", type=Path, default=None, help="write each path's nodes (mm) to SAVE-path.npz"
    )
    ap.add_argument(
        "--solver-threads",
        type=int,
        default=1,
        help="MKL PARDISO's threads, as `fruit --solver-threads` (default 1)",
    )
    args = ap.parse_args()
    from fruitcli.fem.solver import pardiso

    pardiso.use_threads(args.solver_threads)
    from bench_fem import scene_loads
    from run_all import commit, processor

    from fruitcli.fem.stage import state_loads
    from fruitcli.fem.state_load import Load
    from fruitcli.scene import load_scene

    scene = load_scene(ROOT / "pipelines" / "fruit-breathing.toml", must_exist=False)
    stamp = (
        f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC, commit {commit()}, "
        f"{processor()}, {os.cpu_count()} cores, PARDISO on {args.solver_threads} thread(s)"
    )
    with tempfile.TemporaryDirectory() as tmp:
        mesh_dir = args.mesh or Path(tmp)
        mesh_dir.mkdir(parents=True, exist_ok=True)
        npz = default_mesh(mesh_dir, scene)
        if args.first:
            print(f"the default Fruit's first breathing state from rest; {stamp}")
            run_first(scene, npz, args)
            return

        def breathing(names):
            return scene_loads(scene, names, 10**6)

        def sweep(names):
            peak = max(load.pressure_kpa[0] for load in state_loads(scene, names))
            out = []
            for t in np.linspace(0.0, 1.0, args.sweep + 1)[1:]:
                pk = np.zeros(len(names))
                pk[0] = t * peak
                out.append(Load.pressures(pk))
            return out

        paths = [("breathing", breathing), ("sweep", sweep)]
        print(f"quadratic state from the previous one, default Fruit; {stamp}")
        for name, loads_of in paths:
            if args.only and name != args.only:
                continue
            medians = []
            for _ in range(args.repeat):
                before = load_text()
                run = run_path(scene, npz, loads_of)
                after = load_text()
                later_ms = run["ms"][1:]
                st = run["later_stats"]
                med = float(np.median(later_ms))
                medians.append(med)
                if args.save is not None:
                    xs = np.stack([s.x for s in run["states"]])
                    np.savez(f"{args.save}-{name}.npz", x=xs)
                print(
                    f"{name}: {len(later_ms)} states after the one from rest "
                    f"({len(run['model'].conn)} tets, {len(run['model'].pattern.free)} dofs): "
                    f"median {med:.0f} ms (min {later_ms.min():.0f}, max {later_ms.max():.0f}), "
                    f"CPU median {np.median(run['cpu_ms'][1:]):.0f} ms (both cores), "
                    f"from rest {run['ms'][0]:.0f} ms; Newton {run['iterations'][1:].mean():.2f}"
                    f" per state, CG {st['cg_iterations'] / len(later_ms):.1f} per state, "
                    f"{st['factorizations']} factorizations; assembly "
                    f"{1e3 * st['assembly_s'] / len(later_ms):.0f} ms, factor "
                    f"{1e3 * st['factor_s'] / len(later_ms):.0f} ms per state; "
                    f"{_work_text(run['later_work'], len(later_ms))}; "
                    f"load average {before} -> {after}",
                    flush=True,
                )
            if args.repeat > 1:
                runs = " ".join(f"{m:.0f}" for m in medians)
                print(f"{name}: medians of {args.repeat} runs: {runs}")


if __name__ == "__main__":
    main()
