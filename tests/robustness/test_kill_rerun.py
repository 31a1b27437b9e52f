"""A `fruit run` stopped anywhere (Ctrl-C or SIGKILL) and run again gives the outputs of a
clean run, reuses the stages that had finished, and leaves no temporary folder behind."""

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.compare_runs import compare

pytestmark = pytest.mark.slow

# A flat pad bent by a jig: every kind of stage (gmsh child, FEM, bench, locate, evaluate,
# sensitivity) in about 5 s.
SCENE = """
[scene]
name = "kill-rerun"
[geometry]
pad_size_mm = [40.0, 40.0, 3.0]
[grid]
count = [2, 2]
spacing_x_mm = 16.0
spacing_y_mm = 16.0
[mesh]
size_mm = 4.0
[fem]
element = "p1"
[material]
model = "neo-hookean"
young_modulus_kpa = 100.0
poisson_ratio = 0.45
density_kg_m3 = 1070.0
[[fixed]]
box_mm = [-21.0, -21.0, -1.0, -14.0, 21.0, 4.0]
[[jig]]
region_box_mm = [14.0, -21.0, -1.0, 21.0, 21.0, 4.0]
rotate_deg = -30.0
axis = [0.0, 1.0, 0.0]
pivot_mm = [0.0, 0.0, 20.0]
stiffness_n_per_mm = 10.0
[solver]
jig_steps = 3
[sensitivity]
noise_frames = 50
[bench]
indenters = ["small"]
"""

STAGES = ["pad-grid", "tetra", "simulate", "bench", "locate", "evaluate", "sensitivity"]
# (the progress line the signal follows, the stage running then, signal); the stages
# before it have finished
KILL_POINTS = [
    ("tetra: gmsh at size", "tetra", signal.SIGKILL),
    ("tetra: gmsh at size", "tetra", signal.SIGINT),
    ("simulate: run", "simulate", signal.SIGINT),
    ("state 1/1", "simulate", signal.SIGKILL),
    ("bench: run", "bench", signal.SIGKILL),
    ("locate: run", "locate", signal.SIGINT),
    ("sensitivity: run", "sensitivity", signal.SIGKILL),
]


def _fruit(*args):
    code = "from fruitcli.cli.main import main; main()"  # as the console script
    return [sys.executable, "-c", code, *map(str, args)]


def _env():
    """The child's environment: this checkout's fruitcli, no plot windows, no buffering."""
    root = str(Path(__file__).resolve().parents[2])
    return dict(os.environ, MPLBACKEND="Agg", PYTHONUNBUFFERED="1", PYTHONPATH=root)


def _run_until(scene: Path, out: Path, line: str, sig: int, delay_s: float):
    """Start `fruit run`, send `sig` `delay_s` after `line` appears; return (code, output)."""
    proc = subprocess.Popen(
        _fruit("run", scene, "--out", out),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=_env(),
    )
    seen = []
    for text in proc.stdout:
        seen.append(text)
        if line in text:
            time.sleep(delay_s)
            proc.send_signal(sig)
            break
    seen.extend(proc.stdout)
    return proc.wait(timeout=120), "".join(seen)


def _leftovers(out: Path) -> list[str]:
    names = (".tmp", ".copying", ".partial", "fruit-gmsh")
    return [str(p) for p in out.rglob("*") if any(n in p.name for n in names)]


def _plan(output: str) -> dict[str, str]:
    """The rerun's closing plan: stage -> action."""
    plan = {}
    for text in output.splitlines():
        parts = text.split()
        if parts and parts[0] in STAGES and len(parts) > 1 and parts[1] in ("run", "reuse"):
            plan[parts[0]] = parts[1]
    return plan


def test_a_run_killed_anywhere_and_run_again_equals_a_clean_run(tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE)
    clean = tmp_path / "clean" / "out"  # one parent each: no stage lent between siblings
    done = subprocess.run(
        _fruit("run", scene, "--out", clean), capture_output=True, text=True, env=_env()
    )
    assert done.returncode == 0, done.stdout + done.stderr
    rng = random.Random(29)
    for i, (line, running, sig) in enumerate(KILL_POINTS):
        out = tmp_path / f"killed-{i}" / "out"
        code, output = _run_until(scene, out, line, sig, rng.uniform(0.0, 0.3))
        where = f"{sig.name} after {line!r}"
        assert line in output, f"{where}: the run never printed it:\n{output}"
        if sig == signal.SIGKILL:
            assert code == -signal.SIGKILL, f"{where}: exit {code}\n{output}"
        else:  # one line and exit 130, or the run had already ended
            assert code in (130, 0), f"{where}: exit {code}\n{output}"
            if code == 130:
                assert "Traceback" not in output, output
                assert output.rstrip().splitlines()[-1] == "Interrupted.", output
        again = subprocess.run(
            _fruit("run", scene, "--out", out), capture_output=True, text=True, env=_env()
        )
        assert again.returncode == 0, f"{where}: the rerun failed:\n{again.stdout}{again.stderr}"
        assert compare(clean, out) == [], f"{where}: the rerun differs from a clean run"
        assert _leftovers(out) == [], f"{where}: temporary files left"
        finished = STAGES[: STAGES.index(running)]
        plan = _plan(again.stdout)
        for stage in finished:  # a stage that had finished is not run again
            assert plan.get(stage) == "reuse", f"{where}: {stage} {plan.get(stage)}"


def test_a_sweep_interrupted_at_random_instants_and_run_again_equals_a_clean_sweep(tmp_path):
    """`fruit sweep --jobs 2` stopped by a terminal's Ctrl-C (the signal to its whole
    process group) at random instants: one line "Interrupted." and exit 130, no worker's
    traceback; the sweep run again gives each variant's outputs of a clean sweep."""
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE)
    sweep = ["sweep", scene, "--set", "bench.seed=0,1", "--jobs", "2", "--out"]
    clean = tmp_path / "clean" / "out"
    done = subprocess.run(_fruit(*sweep, clean), capture_output=True, text=True, env=_env())
    assert done.returncode == 0, done.stdout + done.stderr
    variants = sorted(p.name for p in (clean / "variants").iterdir())
    assert len(variants) == 2
    rng = random.Random(41)
    for i in range(3):
        out = tmp_path / f"stopped-{i}" / "out"
        delay = rng.uniform(0.5, 8.0)
        proc = subprocess.Popen(
            _fruit(*sweep, out),
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=_env(),
            start_new_session=True,  # its own process group, as a terminal's foreground job
        )
        time.sleep(delay)
        os.killpg(proc.pid, signal.SIGINT)
        output = proc.communicate(timeout=300)[0]
        where = f"Ctrl-C {delay:.2f} s into the sweep"
        assert proc.returncode in (130, 0), f"{where}: exit {proc.returncode}\n{output}"
        assert "Traceback" not in output and "KeyboardInterrupt" not in output, output
        if proc.returncode == 130:
            assert output.rstrip().splitlines()[-1] == "Interrupted.", output
        again = subprocess.run(_fruit(*sweep, out), capture_output=True, text=True, env=_env())
        assert again.returncode == 0, f"{where}: the rerun failed:\n{again.stdout}{again.stderr}"
        for name in variants:
            differ = [  # a variant's logs hold its process ids and times
                d
                for d in compare(clean / "variants" / name, out / "variants" / name)
                if not d.startswith(("attempts.log:", "log.txt:"))
            ]
            assert differ == [], f"{where}: variant {name} differs from a clean sweep: {differ}"
        assert _leftovers(out) == [], f"{where}: temporary files left"
