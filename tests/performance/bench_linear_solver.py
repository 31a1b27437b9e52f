"""Benchmark: `fruit simulate` of a bundled scene with MKL PARDISO (the optional extra
`fruit-touch[pardiso]`) and without it (the default install: SciPy's SuperLU for the
quadratic elements; `tests/performance/without_pardiso.py`), on the same mesh and taxels.

Each line: the path, the whole command's wall time, the sum of the states' solve times
(states.npz solve_ms), the Newton iterations, and the largest node distance from the
PARDISO run's states (mm). The load average is printed before and after (2 cores shared:
compare figures taken at a like load). With --docs the figures, date, commit and machine
go to docs/data/linear-solvers.json, from which `make docs` writes a section of the
performance page.

With --refusals, also the default Fruit's refusals of a pressure past a chamber's
collapse and limit (`bench_refusal.py`), per path.

Run: .venv/bin/python tests/performance/bench_linear_solver.py [--scene FILE]
[--paths pardiso default] [--refusals] [--docs]
"""

import argparse
import datetime
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
MAX_RUNS = 1  # the breathing takes 1-3 minutes per path

PATHS = {
    "pardiso": ("MKL PARDISO (pip install 'fruit-touch[pardiso]')", True),
    "default": ("default install: SuperLU in symmetric mode", False),
}
"""name -> (what it is, whether PARDISO is used: else through without_pardiso.py)."""


def fruit(args: list, with_pardiso: bool) -> tuple[float, subprocess.CompletedProcess]:
    """Run `fruit args`, through without_pardiso.py unless with_pardiso."""
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT))
    if with_pardiso:
        cmd = [sys.executable, "-c", "from fruitcli.cli.main import main; main()"]
    else:
        cmd = [sys.executable, str(HERE / "without_pardiso.py")]
    t0 = time.perf_counter()
    res = subprocess.run([*cmd, *map(str, args)], env=env, capture_output=True, text=True)
    return time.perf_counter() - t0, res


def refusal_rows(paths: list[str], tmp: Path) -> list[dict]:
    """`fruit simulate` of the default Fruit with c1 at -500 kPa (past its collapse) and
    2000 kPa (past its limit), refused by the limits check (`bench_refusal.py`), per
    path: the seconds from the mesh to the refusal and whether its line is the first
    path's."""
    from bench_refusal import fruit_scene, refusal

    rows: list = []
    first: dict = {}
    for name in paths:
        for p in (-500.0, 2000.0):
            scene = tmp / f"refuse_{name}_{p:g}.toml"
            scene.write_text(fruit_scene(p))
            after, wall, code, last = refusal(scene, tmp / f"o_{name}_{p:g}", PATHS[name][1])
            first.setdefault(p, last)
            rows.append(
                {
                    "path": name,
                    "what": PATHS[name][0],
                    "c1_kpa": p,
                    "after_mesh_s": None if after is None else round(after, 1),
                    "exit_code": code,
                    "same_line": last == first[p],
                }
            )
            print(
                f"{name}: c1 at {p:g} kPa refused in {after or 0:.1f} s after the mesh, "
                f"exit {code}, the same line as the first path's: {last == first[p]}"
            )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", type=Path, default=ROOT / "pipelines" / "fruit-breathing.toml")
    ap.add_argument("--paths", nargs="+", default=list(PATHS), choices=list(PATHS))
    ap.add_argument("--docs", action="store_true", help="write docs/data/linear-solvers.json")
    ap.add_argument(
        "--refusals",
        action="store_true",
        help="also bench_refusal's default Fruit cases (c1 at -500 and 2000 kPa) per path",
    )
    args = ap.parse_args()
    sys.path.insert(0, str(HERE))
    from run_all import commit, processor

    version = commit()
    load0 = os.getloadavg()
    print(f"load average before: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    rows, reference = [], None
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        wall, res = fruit(["run", args.scene, "--until", "make-tracks", "--out", tmp / "s"], True)
        if res.returncode != 0:
            sys.exit(f"make-tracks failed: {res.stderr.strip().splitlines()[-1:]}")
        tracks = tmp / "s" / "make-tracks"
        common = ["--solid", tracks / "reduced.stl", "--taxels", tracks / "taxels.csv"]
        for name in args.paths:
            what, with_pardiso = PATHS[name]
            out = tmp / name
            wall, res = fruit(["simulate", args.scene, *common, "--out", out], with_pardiso)
            if res.returncode != 0:
                print(f"{name}: failed ({res.stderr.strip().splitlines()[-1:]})")
                continue
            with np.load(out / "states.npz") as z:
                solve_s = float(np.sum(z["solve_ms"])) / 1000.0
                iterations = int(np.sum(z["iterations"]))
                nodes = z["rest_nodes"][None] + z["displacement_mm"]
            reference = nodes if reference is None else reference
            diff = float(np.abs(nodes - reference).max())
            rows.append(
                {
                    "path": name,
                    "what": what,
                    "wall_s": round(wall, 1),
                    "solve_s": round(solve_s, 1),
                    "states": len(nodes),
                    "newton_iterations": iterations,
                    "max_node_difference_mm": diff,
                }
            )
            print(
                f"{name}: wall {wall:.1f} s, states' solves {solve_s:.1f} s, "
                f"{len(nodes)} states, {iterations} Newton iterations, "
                f"largest node difference from the first path {diff:.2g} mm"
            )
        refusals = refusal_rows(args.paths, tmp) if args.refusals else []
    load1 = os.getloadavg()
    print(f"load average after: {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    if args.docs:
        data = ROOT / "docs" / "data" / "linear-solvers.json"
        data.write_text(
            json.dumps(
                {
                    "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                    "commit": version,
                    "machine": f"{processor()}, {os.cpu_count()} cores",
                    "load_average_before": [round(v, 2) for v in load0],
                    "load_average_after": [round(v, 2) for v in load1],
                    "scene": args.scene.resolve().relative_to(ROOT).as_posix(),
                    "rows": rows,
                    "refusals": refusals,
                },
                indent=1,
            )
            + "\n"
        )
        print(f"wrote {data}")


if __name__ == "__main__":
    main()
