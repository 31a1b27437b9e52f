"""Benchmark: how soon `fruit simulate` refuses a chamber pressure past the chamber's
limit pressure (inflation) or collapse (suction) (`fruitcli.fem.pressure_check.check_pressures`).

1. A thick sphere (outer radius 20 mm: an icosphere of 1,280 faces; cavity radius 10 mm;
   E = 100 kPa, nu = 0.45, `[mesh] size_mm = 3`, the default quadratic element; no
   support: the 3-2-1 one) with its cavity at -500 kPa and at 2000 kPa.
2. The default Fruit (pipelines/fruit-breathing.toml: gravity, fixed base) with chamber
   c1 at -500 kPa and at 2000 kPa, the others at 0 (skip with --no-fruit).

Each line: the time from the mesh (the tetra stage's last line) to the refusal, the
whole command's wall time, the exit code and the refusal's first words. The load
average is printed before and after (2 cores shared: compare figures taken at a like
load). With --again each Fruit case runs a second time into the same output folder:
the check then takes its samples from the first run's pressure-check.npz
(`fruitcli.fem.sample_cache`).

Run: .venv/bin/python tests/performance/bench_refusal.py [--no-fruit] [--without-pardiso]
     [--again] [--solver-threads N]
(--without-pardiso: as the default install, through tests/performance/without_pardiso.py;
--solver-threads N: `fruit --solver-threads N simulate`)
"""

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
MAX_RUNS = 1  # four `fruit simulate` runs of 10-35 s each

SPHERE = """[geometry]
solid = "ball.stl"
[[geometry.chamber]]
name = "cavity"
ellipsoid = {{center_mm = [0.0, 0.0, 0.0], radii_mm = [10.0, 10.0, 10.0]}}
[mesh]
size_mm = 3
[material]
young_modulus_kpa = 100
poisson_ratio = 0.45
[actuation]
pressure_kpa = {{ cavity = [{p}] }}
"""


def fruit_scene(pressure: float) -> str:
    """The default Fruit's scene with c1 at `pressure` (kPa), c2 and c3 at 0, one state."""
    text = (ROOT / "pipelines" / "fruit-breathing.toml").read_text()
    artist = ROOT / "data" / "generated" / "fruit_artist.ply"
    text = re.sub(r'(?m)^artist = "[^"]*"', f'artist = "{artist}"', text)
    return re.sub(
        r"(?m)^pressure_kpa = .*$",
        f"pressure_kpa = {{ c1 = [{pressure}], c2 = [0.0], c3 = [0.0] }}",
        text,
    )


def refusal(
    scene: Path, out: Path, pardiso: bool = True, threads: int = 1
) -> tuple[float | None, float, int, str]:
    """`fruit simulate` on `scene` (without MKL PARDISO, as the default install, unless
    `pardiso`; PARDISO on `threads` threads): (seconds from the mesh to its last line or
    None, wall seconds, exit code, last line)."""
    fruit = [str(Path(sys.executable).parent / "fruit")]
    if not pardiso:
        fruit = [sys.executable, str(HERE / "without_pardiso.py")]
    t0 = time.monotonic()
    proc = subprocess.Popen(
        [*fruit, "--solver-threads", str(threads), "simulate", str(scene), "--out", str(out)],
        cwd=scene.parent,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=os.environ | {"MPLBACKEND": "Agg"},
    )
    meshed, last, at = None, "", 0.0
    assert proc.stdout is not None  # stdout=PIPE
    for line in proc.stdout:
        now = time.monotonic() - t0
        if re.search(r"tetra: \d+ tets", line):
            meshed = now
        if line.strip():
            last, at = line.strip(), now
    code = proc.wait()
    return (None if meshed is None else at - meshed), time.monotonic() - t0, code, last


def children_cpu() -> float:
    """CPU seconds (user + system, all threads) of the finished child processes."""
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def refuse(scene: Path, out: Path, pardiso: bool = True, threads: int = 1) -> str:
    """One line: `refusal` of `scene`, timed from the mesh to its last line (wall), and
    the whole command's CPU time (all threads, meshing included)."""
    cpu0 = children_cpu()
    after, wall, code, last = refusal(scene, out, pardiso, threads)
    cpu = children_cpu() - cpu0
    when = "?" if after is None else f"{after:.1f} s"
    return f"{when} after the mesh, {wall:.1f} s in all ({cpu:.1f} s CPU), exit {code}: {last[:90]}"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--no-fruit", action="store_true")
    parser.add_argument(
        "--without-pardiso", action="store_true", help="as the default install: no MKL PARDISO"
    )
    parser.add_argument(
        "--again", action="store_true", help="run each Fruit case again in the same folder"
    )
    parser.add_argument("--solver-threads", type=int, default=1, help="MKL PARDISO's threads")
    args = parser.parse_args()
    pardiso = not args.without_pardiso
    threads = args.solver_threads
    print(f"PARDISO on {threads} thread(s)")
    print(f"load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        import trimesh

        trimesh.creation.icosphere(3, 20.0).export(tmp / "ball.stl")
        for p in (-500.0, 2000.0):
            scene = tmp / f"sphere_{p:g}.toml"
            scene.write_text(SPHERE.format(p=p))
            line = refuse(scene, tmp / f"o_sphere_{p:g}", pardiso, threads)
            print(f"thick sphere, cavity at {p:g} kPa: {line}")
        if not args.no_fruit:
            for p in (-500.0, 2000.0):
                scene = tmp / f"fruit_{p:g}.toml"
                scene.write_text(fruit_scene(p))
                line = refuse(scene, tmp / f"o_fruit_{p:g}", pardiso, threads)
                print(f"default Fruit, c1 at {p:g} kPa: {line}", flush=True)
                if args.again:
                    line = refuse(scene, tmp / f"o_fruit_{p:g}", pardiso, threads)
                    print(f"default Fruit, c1 at {p:g} kPa, again: {line}", flush=True)
    print(f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
