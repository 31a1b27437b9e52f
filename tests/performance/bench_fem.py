"""Benchmark: the mechanics on the default fruit (reduced.stl from make-tracks with the
3 chambers of pipelines/fruit-breathing.toml): tetra time, time per new pressure state
from the previous one, Newton iterations, assembly time, ratio to one scipy sparse
direct solve of the same K, linear solvers compared, time per state against mesh size;
and the touchpad's 180-degree bend by jig springs (pipelines/touchpad-4x4.toml, one state
in jig_steps load steps).

At the default size the breathing is timed three ways: the scene's states in their
first cycle (the predictor's history still filling), the same states in cycles 2-3 (a
running animation), and the cycle sampled at 30 Hz (a periodic spline through the
scene's states: the live rate of the target).

And Lame's thick sphere as the mesh is refined (accuracy against run time).

The tables up to the online FEM time the paper's model (linear tets, corotational Hooke,
as SOFA); `bench_elements` then times every element and material of [fem] / [material]
on the default mesh, and the default scenes' own (p2, neo-Hookean).

Run: .venv/bin/python tests/performance/bench_fem.py [--sizes 8 6 5 4] [--states 13] [--no-pad]
     [--lame-sizes 3 2 1.5] [--p1-only] [--factor]
"""

import argparse
import dataclasses
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def hwm_mb() -> float:
    """Peak RSS of this process image from /proc (ru_maxrss survives fork + exec, so a
    child started by a big parent would report the parent's peak)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return float(line.split()[1]) / 1024.0
    return rss_mb()


def fruit_solid(tmp: Path) -> Path:
    from fruitcli.geometry.artist import write_artist
    from fruitcli.geometry.tracks.make_tracks import make_tracks

    art = tmp / "fruit.stl"
    write_artist(art)
    make_tracks(art, tmp / "tracks")
    return tmp / "tracks" / "reduced.stl"


def scene_loads(scene, names, n_states: int, cycles: int = 1) -> list:
    """The scene's first n_states loads, repeated `cycles` times (a last state equal to
    the first, which closes the cycle, is solved once per cycle)."""
    from fruitcli.fem.stage import state_loads

    loads = state_loads(scene, names)[:n_states]
    if (
        cycles > 1
        and len(loads) > 2
        and np.array_equal(loads[0].pressure_kpa, loads[-1].pressure_kpa)
    ):
        loads = loads[:-1]
    return loads * cycles


def live_loads(scene, names, rate_hz: float, cycles: int) -> list:
    """The scene's pressure cycle sampled at rate_hz: a periodic cubic spline through
    its states spread evenly over [actuation].period_s (the last state closes the cycle)."""
    from scipy.interpolate import CubicSpline

    from fruitcli.fem.stage import state_loads
    from fruitcli.fem.state_load import Load

    table = np.array([ld.pressure_kpa for ld in state_loads(scene, names)])
    period = scene.actuation.period_s
    spline = CubicSpline(np.linspace(0.0, period, len(table)), table, bc_type="periodic")
    t = np.arange(0.0, cycles * period, 1.0 / rate_hz) % period
    return [Load.pressures(row) for row in spline(t)]


def time_states(
    scene,
    mesh_npz,
    solver_name: str,
    n_states: int,
    loads=None,
    keep_states: bool = False,
    stats_log: list | None = None,
):
    """Solve the scene's states (or `loads`, a function of the chamber names) in order
    with one reused solver; returns (model, solver, rows (ms, iterations, cg, cpu ms)[,
    the StateResults]); a copy of the solver's stats after each state goes to
    `stats_log`."""
    from fruitcli.fem import io
    from fruitcli.fem.solver.state import solve_state
    from fruitcli.fem.stage import build_model, solver_options

    model = build_model(scene, io.load_mesh(mesh_npz))
    loads = (loads or (lambda names: scene_loads(scene, names, n_states)))(model.chamber_names)
    solver = model.make_solver(solver_name)
    opts = dataclasses.replace(solver_options(scene), linear_solver=solver_name)
    x = p = prev = None
    rows, states = [], []
    for load in loads:
        cg0 = solver.stats["cg_iterations"]
        cpu0 = time.process_time()
        res = solve_state(
            model, load, x_start=x, load_start=prev, pressure_start=p, options=opts, solver=solver
        )
        rows.append(
            (
                res.solve_ms,
                res.iterations,
                solver.stats["cg_iterations"] - cg0,
                1e3 * (time.process_time() - cpu0),
            )
        )
        if stats_log is not None:
            stats_log.append(dict(solver.stats))
        states.append(res)
        x, p, prev = res.x, res.pressure_kpa, load
    return (model, solver, rows, states) if keep_states else (model, solver, rows)


def breathing_runs(scene, mesh_npz, n_states: int) -> list:
    """[(label, rows)] of the three timings of the breathing (see the module docstring);
    rows exclude each run's first state, solved from rest."""
    _, _, rows = time_states(
        scene,
        mesh_npz,
        "pcg",
        n_states,
        lambda names: scene_loads(scene, names, n_states, cycles=3),
    )
    per_cycle = len(rows) // 3  # one row per state solved
    _, _, live = time_states(
        scene, mesh_npz, "pcg", n_states, lambda names: live_loads(scene, names, LIVE_HZ, cycles=2)
    )
    return [
        (
            f"scene's states, first cycle ({per_cycle - 1} after the one from rest, "
            "history filling)",
            rows[1:per_cycle],
        ),
        ("scene's states, cycles 2-3 (running animation)", rows[per_cycle:]),
        (f"the whole cycle sampled at {LIVE_HZ:g} Hz, second cycle", live[len(live) // 2 :]),
    ]


LIVE_HZ = 30.0


def bench_online(scene, mesh_npz, taxels_csv, seconds: float = 6.0) -> None:
    """`fruit live --online` without hardware: the online FEM thread follows the
    breathing pressures as they change in wall-clock time (the scene's cycle, a periodic
    spline) while the main thread pushes board frames through the live locator as fast as
    it can. Prints the states solved per second, the time per state (the taxels' lag
    behind the pressures), and the live loop's time per frame with and without the
    thread."""
    import threading

    from scipy.interpolate import CubicSpline

    from fruitcli.fem import io
    from fruitcli.fem.elements import barycentric
    from fruitcli.fem.online import OnlineSolver
    from fruitcli.fem.stage import build_model, solver_options, state_loads
    from fruitcli.sensing.detection.frames_to_touches import Locator
    from fruitcli.sensing.detection.settings import Settings
    from fruitcli.sensing.live.board_emulator import synthetic_frames
    from fruitcli.sensing.live.loop import LiveLocator
    from fruitcli.tables import read_taxels

    model = build_model(scene, io.load_mesh(mesh_npz))
    taxels = read_taxels(taxels_csv)
    tet, w, _ = barycentric.locate(model.rest, model.tets, taxels.xyz_mm)
    online = OnlineSolver(model, tet, w, solver_options(scene))
    table = np.array([ld.pressure_kpa for ld in state_loads(scene, model.chamber_names)])
    period = scene.actuation.period_s
    spline = CubicSpline(np.linspace(0.0, period, len(table)), table, bc_type="periodic")
    online.update(spline(0.0))  # the first state, from rest, before the clock starts
    settings = Settings.from_scene(scene.detection)
    frames = synthetic_frames(2000, seed=4)

    def frame_times(follower):
        loc = Locator(taxels, scene.board, online.taxels_mm, settings)
        live = LiveLocator(loc, None, follower)
        ms = []
        t_end = time.perf_counter() + seconds
        n = 0
        while time.perf_counter() < t_end:
            t0 = time.perf_counter()
            live.push(frames[n % len(frames)], t0)
            ms.append(1e3 * (time.perf_counter() - t0))
            n += 1
            time.sleep(0.0005)  # a board delivers frames, it does not flood the loop
        return np.array(ms)

    alone = frame_times(None)
    t_start = time.perf_counter()
    stop = threading.Event()

    def source():
        return spline((time.perf_counter() - t_start) % period)

    solved0 = len(online.solve_ms)
    th = online.run(source, stop)
    with_fem = frame_times(online)
    stop.set()
    th.join(5)
    solves = np.array(online.solve_ms[solved0:])
    print(
        f"\nonline FEM (fruit live --online) on the breathing in real time, {seconds:g} s: "
        f"{len(solves) / seconds:.0f} states solved per second, {np.median(solves):.1f} ms "
        f"median per state (the taxels' lag behind the pressures), "
        f"{online.failures} failed"
    )
    print(
        f"live loop per frame: {np.median(alone):.3f} ms median alone, "
        f"{np.median(with_fem):.3f} ms with the FEM thread (p99 {np.percentile(alone, 99):.3f}"
        f" and {np.percentile(with_fem, 99):.3f} ms)"
    )


def one_direct_solve_ms(model) -> tuple[float, float]:
    """(assembly ms, scipy spsolve ms) of the rest tangent."""
    import scipy.sparse.linalg as spla

    from fruitcli.fem.materials import corotation

    rot = np.tile(np.eye(3), (len(model.tets), 1, 1))
    t0 = time.perf_counter()
    k = model.pattern.assemble(corotation.warped_stiffness(model.k0, rot), model.spring_diag)
    t_asm = time.perf_counter() - t0
    b = np.ones(k.shape[0])
    t0 = time.perf_counter()
    spla.spsolve(k.tocsc(), b)
    return 1e3 * t_asm, 1e3 * (time.perf_counter() - t0)


def bench_pad(tmp: Path, tolerance: float | None) -> None:
    """The touchpad bend: tetra, then the one jig state in the scene's jig_steps."""
    from fruitcli.fem import io
    from fruitcli.fem.solver.state import solve_state
    from fruitcli.fem.stage import build_model, run_tetra, solver_options, state_loads
    from fruitcli.scene import load_scene

    scene = load_scene(ROOT / "pipelines" / "touchpad-4x4.toml", must_exist=False)
    cfg = scene.solver
    tol = cfg.tolerance if tolerance is None else tolerance
    q = run_tetra(scene, None, tmp / "pad-mesh")
    model = build_model(scene, io.load_mesh(tmp / "pad-mesh" / "mesh.npz"))
    load = state_loads(scene, model.chamber_names)[0]
    solver = model.make_solver(cfg.linear_solver)
    opts = dataclasses.replace(solver_options(scene, first_state=True), tolerance=tol)
    res = solve_state(model, load, options=opts, solver=solver)
    st = solver.stats
    print(
        f"\ntouchpad bend: {q['n_tets']} tets, {cfg.jig_steps} jig steps, tolerance {tol:g}: "
        f"{res.solve_ms / 1e3:.2f} s, {res.iterations} Newton iterations, "
        f"{res.subdivisions} subdivisions, {st['factorizations']} factorizations "
        f"({st['factor_s']:.2f} s), {st['cg_iterations']} CG iterations, residual "
        f"{res.residual:.1e}"
    )


LAME_SCENE = """
[geometry]
solid = "ball.stl"
[[geometry.chamber]]
name = "c"
ellipsoid = {{center_mm = [0.0, 0.0, 0.0], radii_mm = [10.0, 10.0, 10.0]}}
[mesh]
size_mm = {size}
min_size_mm = {cavity}
[fem]
element = "{element}"
[material]
model = "{model}"
young_modulus_kpa = 100.0
poisson_ratio = {nu}
[actuation]
pressure_kpa = {{c = [0.1]}}
"""


def bench_lame(tmp: Path, sizes: list[float], p2_sizes: list[float]) -> None:
    """Lame's thick sphere (cavity a = 10, ball b = 20 mm, E = 100 kPa, 0.1 kPa, free):
    the chamber's compliance dV/dp against the closed form as the mesh is refined (size,
    cavity size = size / 2), with tets and the time of tetra + simulate: the paper's
    model (p1, corotational) at nu = 0.3 on `sizes`, the default element (p2,
    neo-Hookean) at nu = 0.3, 0.49 and 0.4999 on `p2_sizes`."""
    import trimesh

    from fruitcli.fem.stage import run_simulate, run_tetra
    from fruitcli.scene import parse_scene

    trimesh.creation.icosphere(3, 20.0).export(tmp / "ball.stl")
    a, b, p = 10.0, 20.0, 0.1
    print("\nLame's thick sphere, compliance dV/dp against the closed form:")
    print(
        f"{'element':>8} {'nu':>6} {'size_mm':>7} {'cavity':>6} {'tets':>7} {'dV/dp':>7} "
        f"{'exact':>7} {'error':>7} {'time_s':>6}"
    )
    runs = [("p1", "corotational", 0.3, size) for size in sizes]
    runs += [("p2", "neo-hookean", nu, size) for nu in (0.3, 0.49, 0.4999) for size in p2_sizes]
    for element, model, nu, size in runs:
        u_a = p * a**3 / (100.0 * (b**3 - a**3)) * ((1 - 2 * nu) * a + (1 + nu) * b**3 / (2 * a**2))
        exact = 4 * np.pi * a**2 * u_a / p
        text = LAME_SCENE.format(size=size, cavity=size / 2, element=element, model=model, nu=nu)
        scene = parse_scene(text, tmp / "lame.toml")
        out = tmp / f"lame-{element}-{nu:g}-{size:g}"
        t0 = time.perf_counter()
        q = run_tetra(scene, None, out)
        run_simulate(scene, out / "mesh.npz", None, out)
        st = np.load(out / "states.npz", allow_pickle=False)
        dv = (st["chamber_volume_mm3"][0, 0] - st["chamber_rest_volume_mm3"][0]) / p
        print(
            f"{element:>8} {nu:6g} {size:7g} {size / 2:6g} {q['n_tets']:7d} {dv:7.2f} "
            f"{exact:7.2f} {100 * (dv / exact - 1):+6.1f}% {time.perf_counter() - t0:6.1f}",
            flush=True,
        )


def paper_model(scene):
    """The scene with the paper's SOFA model: linear tets, corotational Hooke."""
    return scene.with_values({"fem.element": "p1", "material.model": "corotational"})


PHASES = [
    ("precond_s", "triangular solves (CG's preconditioner)"),
    ("product_s", "tangent products"),
    ("update_s", "tangent updates (rotation term, pressure stiffness)"),
    ("factor_s", "factorizations"),
]


def bench_p1_breathing(scene0, mesh_npz: Path, n_states: int) -> tuple[float, float]:
    """The paper's model (p1, corotational) on the default fruit's breathing: the
    scene's states in order from rest with one solver, as `fruit simulate` solves them.
    Prints the median wall and CPU time per state from the previous state, the first
    state's from rest, the machine's load, and where the time goes (first run); then the
    median of P1_RUNS such runs with the spread of their medians, and the same with the
    element loops on one thread. Returns (median ms from the previous state over the
    runs, ms from rest)."""
    import os

    import numba

    scene = paper_model(scene0)
    load0 = os.getloadavg()[0]
    log: list = []
    model, solver, rows = time_states(scene, mesh_npz, "pcg", n_states, stats_log=log)
    threads_chosen = numba.get_num_threads()  # by the solver, from the load average
    runs = [rows] + [time_states(scene, mesh_npz, "pcg", n_states)[2] for _ in range(P1_RUNS - 1)]
    from fruitcli.fem import threads as fem_threads

    fem_threads.AUTO = False  # the runs below on a fixed number of threads
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    serial = [time_states(scene, mesh_npz, "pcg", n_states)[2] for _ in range(P1_RUNS)]
    numba.set_num_threads(threads)
    fem_threads.AUTO = True
    load1 = os.getloadavg()[0]
    later = rows[1:]
    wall = np.median([r[0] for r in later])
    cpu = np.median([r[3] for r in later])
    st = {key: log[-1][key] - log[0][key] for key in log[0]}  # after the first state
    st["update_s"] -= st["factor_s"]  # refreshes happen in updates or on a CG retry
    later_s = sum(r[0] for r in later) / 1e3
    print(
        f"\np1 breathing ({len(later)} states after the one from rest, {len(model.tets)} "
        f"tets, nu = {model.poisson_ratio:g}, tolerance {scene.solver.tolerance:g} or "
        f"{scene.solver.displacement_tolerance_mm:g} mm, "
        f"element loops on {threads_chosen} threads (chosen from the load), load average "
        f"{load0:.1f}-{load1:.1f} on {os.cpu_count()} cores):"
    )
    print(
        f"  per state from the previous one: wall {wall:.1f} ms median "
        f"(range {min(r[0] for r in later):.1f}-{max(r[0] for r in later):.1f}), CPU "
        f"{cpu:.1f} ms median; {np.mean([r[1] for r in later]):.2f} Newton and "
        f"{np.mean([r[2] for r in later]):.1f} CG iterations per state"
    )
    print(
        f"  from rest: wall {rows[0][0]:.0f} ms, CPU {rows[0][3]:.0f} ms "
        f"({log[0]['factorizations']} factorizations, {log[0]['factor_s']:.2f} s)"
    )
    print(
        f"  wall time of the {len(later)} states from the previous one ({later_s:.2f} s): "
        + ", ".join(f"{label} {100 * st[key] / later_s:.0f} %" for key, label in PHASES)
        + f" ({st['factorizations']}), the rest (element kernels for the residual, "
        "line search, predictor) "
        f"{100 * (1 - sum(st[k] for k, _ in PHASES) / later_s):.0f} %"
    )
    medians = [float(np.median([r[0] for r in run[1:]])) for run in runs]
    cpus = [float(np.median([r[3] for r in run[1:]])) for run in runs]
    serial_medians = [float(np.median([r[0] for r in run[1:]])) for run in serial]
    print(
        f"  {P1_RUNS} runs of the {len(later)} states: medians "
        + " ".join(f"{m:.1f}" for m in medians)
        + " ms wall, "
        + " ".join(f"{c:.1f}" for c in cpus)
        + " ms CPU (both cores' time); with the "
        "element loops on one thread (numba.set_num_threads(1)): "
        + " ".join(f"{m:.1f}" for m in serial_medians)
        + " ms wall"
    )
    wall = float(np.median(medians))
    direct = float(np.median([one_direct_solve_ms(model)[1] for _ in range(3)]))
    print(
        f"p1 breathing state: median {wall:.1f} ms (from previous state; runs "
        f"{min(medians):.1f}-{max(medians):.1f}), {rows[0][0]:.0f} ms (from rest); "
        f"element loops on one thread {np.median(serial_medians):.1f} ms (target <= 10 ms); "
        f"the machine's speed now: one SciPy direct solve of the rest stiffness "
        f"{direct:.0f} ms, a state {wall / direct:.3f} of it",
        flush=True,
    )
    # the residual tolerance alone, as before [solver] displacement_tolerance_mm
    plain = scene.with_values({"solver.displacement_tolerance_mm": 0.0})
    _, _, rows_p, states_p = time_states(plain, mesh_npz, "pcg", n_states, keep_states=True)
    _, _, _, states = time_states(scene, mesh_npz, "pcg", n_states, keep_states=True)
    moved = max(float(np.abs(a.x - b.x).max()) for a, b in zip(states, states_p, strict=True))
    print(
        f"  with the residual tolerance alone ([solver] displacement_tolerance_mm = 0 "
        f"instead of {scene.solver.displacement_tolerance_mm:g}): wall "
        f"{np.median([r[0] for r in rows_p[1:]]):.1f} ms, CPU "
        f"{np.median([r[3] for r in rows_p[1:]]):.1f} ms median, "
        f"{np.mean([r[1] for r in rows_p[1:]]):.2f} Newton and "
        f"{np.mean([r[2] for r in rows_p[1:]]):.1f} CG iterations per state; the "
        f"default's nodes within {moved:.1e} mm of its states",
        flush=True,
    )
    return wall, rows[0][0]


def bench_factor(scene0, mesh_npz: Path) -> None:
    """The kept factor on the default Fruit's rest tangent, p1 (paper's model) and p2
    (default): PARDISO's analysis + factorization (ordered on the nodes, as the solvers
    do: `pardiso.node_order`, its time included), numerical refactorization and one
    solve (`fruitcli/fem/solver/pardiso.py`), beside cholespy's for p1, and the same in
    single precision, CG's default (with a random right-hand side's relative
    residual)."""
    from fruitcli.fem import io
    from fruitcli.fem.continuum import ContinuumModel
    from fruitcli.fem.solver import linsolve, pardiso
    from fruitcli.fem.stage import build_model

    def timed(fn, *args, n=1):
        """(fn(*args), ms per call over n calls)."""
        t0 = time.perf_counter()
        for _ in range(n):
            out = fn(*args)
        return out, 1e3 * (time.perf_counter() - t0) / n

    if not pardiso.available():
        print("\nkept factor of the rest tangent: skipped, MKL PARDISO is not installed")
        return
    print("\nkept factor of the rest tangent (MKL PARDISO on one thread, no refinement):")
    for label, scene in (("p1", paper_model(scene0)), ("p2", scene0)):
        model = build_model(scene, io.load_mesh(mesh_npz))
        if label == "p1":
            solver = model.make_solver("pcg")
            assert isinstance(solver, linsolve.TangentSolver)
            solver.update(np.tile(np.eye(3), (len(model.tets), 1, 1)))
            k = solver._assemble(False).tocsr()
        else:
            assert isinstance(model, ContinuumModel)
            k = model.tangent(model.rest.copy(), project=True).tocsr()
        upper = linsolve.upper_triangle(k)
        b = np.random.default_rng(0).standard_normal(k.shape[0])
        reps = 50 if label == "p1" else 10
        parts = []
        for single in (False, True):  # single precision: the default of both solvers' CG
            pardiso._LAST_ORDER.clear()  # the node order found again: its time included
            fac, t_fac = timed(pardiso.factorize_upper, upper, None, single, False, k)
            _, t_re = timed(pardiso.factorize_upper, upper, fac, single)
            x = fac.solve(b)
            _, t_solve = timed(fac.solve, b, n=reps)
            miss = np.linalg.norm(k @ x - b) / np.linalg.norm(b)
            entries = fac.iparm[17]
            fac.free()
            kind = "single precision (CG's default)" if single else "double precision"
            parts.append(
                f"{kind}: "
                f"analysis + factorization {t_fac:.0f} ms, refactorization "
                f"{t_re:.0f} ms, one solve {t_solve:.2f} ms, relative residual of a "
                f"solve {miss:.0e}"
            )
        if label == "p1" and linsolve._cholesky is not None:
            chol, t_chol = timed(linsolve._cholesky, k.tocsc())
            chol.solve(b)
            _, t_csolve = timed(chol.solve, b, n=reps)
            parts.append(f"cholespy: factorization {t_chol:.0f} ms, one solve {t_csolve:.2f} ms")
        print(
            f"  {label}, {k.shape[0]} dofs, factor {entries:,} entries; " + "; ".join(parts),
            flush=True,
        )


P1_RUNS = 5
"""Runs of the breathing in `bench_p1_breathing` (each a fresh solver, as `fruit
simulate`): their medians show how much one run's figure varies on this machine."""


ELEMENT_SETTINGS = [
    ("p1", "corotational"),
    ("p1", "neo-hookean"),
    ("p2-pure", "neo-hookean"),
    ("p2", "neo-hookean"),
]


def bench_elements(
    scene0, mesh_npz: Path, n_states: int
) -> dict[tuple[str, str], tuple[float, float]]:
    """Time per breathing state for each element and material on the default mesh: the
    first state from rest, the median of the others from the previous one, and the
    chambers' volume growth at the state with c1 at its peak relative to the default
    element's (what the paper's model costs in accuracy). Returns {(element, material):
    (median ms from the previous state, ms from rest)}."""
    print(f"\nelements on the default fruit's breathing ({n_states} states, pcg):")
    print(
        f"{'element':>8} {'material':>12} {'dofs':>6} {'rest_ms':>8} {'median_ms':>9} "
        f"{'iters':>5} {'factor':>6} {'dV c1/c2/c3 vs p2':>20}"
    )
    growth, times = {}, {}
    for element, material in ELEMENT_SETTINGS:
        scene = scene0.with_values({"fem.element": element, "material.model": material})
        model, solver, rows, states = time_states(
            scene, mesh_npz, "pcg", n_states, keep_states=True
        )
        peak = int(np.argmax([s.pressure_kpa[0] for s in states]))
        growth[(element, material)] = (
            states[peak].chamber_volume_mm3 - model.chamber_rest_volume_mm3
        )
        later = np.array([r[0] for r in rows[1:]])
        times[(element, material)] = (float(np.median(later)), rows[0][0])
        dofs = len(model.pattern.free)
        print(
            f"{element:>8} {material:>12} {dofs:6d} {rows[0][0]:8.0f} {np.median(later):9.1f} "
            f"{np.mean([r[1] for r in rows[1:]]):5.1f} {solver.stats['factorizations']:6d}",
            end="",
            flush=True,
        )
        print()
    ref = growth[("p2", "neo-hookean")]
    for key, g in growth.items():
        print(
            f"  {key[0]:>8} {key[1]:>12}: chamber growth / default element's = "
            + " / ".join(f"{v:.2f}" for v in g / ref)
        )
    return times


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=float, nargs="+", default=[8.0, 6.0, 5.0, 4.0])
    ap.add_argument("--states", type=int, default=13)
    ap.add_argument(
        "--with-jacobi", action="store_true", help="also time Jacobi CG (about 11 s per state here)"
    )
    ap.add_argument("--no-pad", action="store_true", help="skip the touchpad bend")
    ap.add_argument(
        "--lame-sizes",
        type=float,
        nargs="*",
        default=[3.0, 2.0],
        help="mesh sizes of Lame's sphere (1.5 adds about 70 s); none to skip",
    )
    ap.add_argument(
        "--lame-p2-sizes",
        type=float,
        nargs="*",
        default=[6.0, 5.0, 4.0],
        help="mesh sizes of Lame's sphere for the default element",
    )
    ap.add_argument(
        "--p1-only",
        action="store_true",
        help="only the paper's model on the default fruit's breathing",
    )
    ap.add_argument(
        "--factor",
        action="store_true",
        help="only the kept factor's times on the default fruit (p1 and p2)",
    )
    ap.add_argument("--child-states", type=Path, default=None, help=argparse.SUPPRESS)
    ap.add_argument(
        "--pad-tolerance",
        type=float,
        default=None,
        help="override the touchpad scene's [solver] tolerance",
    )
    args = ap.parse_args()
    from fruitcli.fem.solver import linsolve, pardiso
    from fruitcli.scene import load_scene

    if args.child_states is not None:  # peak memory of the simulation alone
        scene = paper_model(
            load_scene(ROOT / "pipelines" / "fruit-breathing.toml", must_exist=False)
        )
        _, _, rows = time_states(scene, args.child_states, "pcg", args.states)
        print(f"{hwm_mb():.0f} {np.median([r[0] for r in rows[1:]]):.1f}")
        return
    from fruitcli.fem.stage import run_tetra

    if args.factor or args.p1_only:  # the default fruit's mesh, then that part alone
        scene_default = load_scene(ROOT / "pipelines" / "fruit-breathing.toml", must_exist=False)
        with tempfile.TemporaryDirectory() as tmp_name:
            tmp = Path(tmp_name)
            run_tetra(paper_model(scene_default), fruit_solid(tmp), tmp / "mesh")
            if args.factor:
                bench_factor(scene_default, tmp / "mesh" / "mesh.npz")
            else:
                bench_p1_breathing(scene_default, tmp / "mesh" / "mesh.npz", args.states)
        return
    scene_default = load_scene(ROOT / "pipelines" / "fruit-breathing.toml", must_exist=False)
    scene0 = paper_model(scene_default)  # the tables below: the paper's model, as before
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        t0 = time.perf_counter()
        solid = fruit_solid(tmp)
        print(
            f"default fruit: make-artist + make-tracks {time.perf_counter() - t0:.1f} s "
            f"-> {solid.name}"
        )
        default_size = scene0.mesh.size_mm
        sizes = sorted(set(args.sizes) | {default_size}, reverse=True)
        backend = (
            "MKL PARDISO"
            if linsolve.USE_PARDISO and pardiso.available()
            else "SuperLU"
            if linsolve._cholesky is None
            else "cholespy"
        )
        print(
            f"kept factorization: {backend}; iters and cg: means per state after the first; "
            "factor: factorizations in all"
        )
        print(
            f"{'size_mm':>7} {'tets':>7} {'nodes':>6} {'tetra_s':>7} {'solver':>10} "
            f"{'median_ms':>9} {'max_ms':>7} {'iters':>5} {'cg':>5} {'factor':>6}"
        )
        for size in sizes:
            scene = scene0.with_values({"mesh.size_mm": size})
            out = tmp / f"mesh-{size:g}"
            t0 = time.perf_counter()
            q = run_tetra(scene, solid, out)
            t_tetra = time.perf_counter() - t0
            solvers = ["pcg"]
            if size == default_size:
                solvers += ["direct"] + (["jacobi"] if args.with_jacobi else [])
            for name in solvers:
                model, solver, rows = time_states(scene, out / "mesh.npz", name, args.states)
                later = np.array([r[0] for r in rows[1:]])  # states from the previous one
                its = np.mean([r[1] for r in rows[1:]])
                cg = np.mean([r[2] for r in rows[1:]])
                print(
                    f"{size:7g} {q['n_tets']:7d} {q['n_nodes']:6d} {t_tetra:7.2f} "
                    f"{name:>10} {np.median(later):9.1f} {later.max():7.1f} {its:5.1f} "
                    f"{cg:5.1f} {solver.stats['factorizations']:6d}",
                    flush=True,
                )
            if size == default_size:
                asm_ms, direct_ms = one_direct_solve_ms(model)
                runs = breathing_runs(scene, out / "mesh.npz", args.states)
                child = subprocess.run(
                    [
                        sys.executable,
                        __file__,
                        "--child-states",
                        str(out / "mesh.npz"),
                        "--states",
                        str(args.states),
                    ],
                    capture_output=True,
                    text=True,
                    check=True,
                )
                default = (size, runs, asm_ms, direct_ms, child.stdout.split())
                default_mesh = out / "mesh.npz"
        size, runs, asm_ms, direct_ms, (child_rss, child_med) = default
        print(
            f"\ndefault size {size:g} mm, one new pressure state from the previous one "
            f"(target <= 33 ms median):"
        )
        for label, rows in runs:
            ms = np.array([r[0] for r in rows])
            print(
                f"  {label}: {np.median(ms):.1f} ms median, {np.percentile(ms, 90):.1f} ms "
                f"90th percentile, max {ms.max():.1f}; "
                f"{np.mean([r[1] for r in rows]):.2f} Newton and "
                f"{np.mean([r[2] for r in rows]):.1f} CG iterations per state"
            )
        med = float(np.median([r[0] for r in runs[0][1]]))
        print(
            f"assembly of the rest K {asm_ms:.1f} ms; one scipy spsolve of it "
            f"{direct_ms:.1f} ms; ratio state (first cycle) / direct solve "
            f"{med / direct_ms:.2f}"
        )
        print(
            f"peak RSS of the {args.states} default states alone (own process: load the mesh, "
            f"build, solve) {child_rss} MB, median state there {child_med} ms "
            f"(target <= 500 MB); this whole benchmark {rss_mb():.0f} MB"
        )
        bench_online(scene0, default_mesh, tmp / "tracks" / "taxels.csv")
        bench_factor(scene_default, default_mesh)
        p1 = bench_p1_breathing(scene_default, default_mesh, args.states)
        times = bench_elements(scene_default, default_mesh, args.states)
        p2 = times[("p2", "neo-hookean")]
        print(
            f"\np1 breathing state: median {p1[0]:.1f} ms (from previous state), "
            f"{p1[1]:.0f} ms (from rest); p2 (the default, neo-Hookean): median "
            f"{p2[0]:.0f} ms (from previous state), {p2[1]:.0f} ms (from rest)"
        )
        if not args.no_pad:
            bench_pad(tmp, args.pad_tolerance)
        if args.lame_sizes:
            bench_lame(tmp, args.lame_sizes, args.lame_p2_sizes)


if __name__ == "__main__":
    main()
