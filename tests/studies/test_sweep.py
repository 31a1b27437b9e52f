"""`fruit sweep`: --set parsing, variants validated like scenes, sweep.csv the same whether
run serially, on 2 local processes or on a Dask LocalCluster of 2 worker processes, a
killed worker's variant rerun elsewhere, failed variants as rows, reruns reusing finished
variants, and bad inputs stopping the sweep before anything runs."""

from __future__ import annotations

import csv
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fruitcli.studies.sweep import (
    SweepError,
    apply_value,
    combinations,
    parse_set,
    short_labels,
    variant_name,
)
from fruitcli.studies.sweep_run import TIMING, figure_inputs, variant_figures

# A 40 x 40 x 3 mm pad, 2 x 2 taxels, its right strip turned 30 degrees by jig springs:
# pad-grid, tetra and simulate in about a second.
PAD = """
[scene]
name = "sweep-pad"
configuration = "Bent"
[geometry]
pad_size_mm = [40.0, 40.0, 3.0]
[grid]
count = [2, 2]
spacing_x_mm = 12.0
spacing_y_mm = 12.0
[mesh]
size_mm = 5.0
[material]
young_modulus_kpa = 100.0
poisson_ratio = 0.45
[[fixed]]
box_mm = [-21.0, -21.0, -1.0, -14.0, 21.0, 4.0]
[[jig]]
region_box_mm = [14.0, -21.0, -1.0, 21.0, 21.0, 4.0]
rotate_deg = -30.0
axis = [0.0, 1.0, 0.0]
pivot_mm = [0.0, 0.0, 20.0]
"""
SETS = ["--set", "mesh.size_mm=4,8", "--set", "material.poisson_ratio=0.3,0.45"]


@pytest.fixture(scope="module")
def pad(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("scene") / "pad.toml"
    path.write_text(PAD)
    return path


def read_rows(path: Path, drop=TIMING) -> list[dict]:
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    return [{k: v for k, v in row.items() if k not in drop} for row in csv.DictReader(lines)]


def attempts(out: Path) -> dict[str, int]:
    return {
        p.parent.name: sum(ln.startswith("variant") for ln in p.read_text().splitlines())
        for p in (out / "variants").glob("*/attempts.log")
    }


def fruit_cmd(*args) -> list[str]:
    return [
        sys.executable,
        "-c",
        "from fruitcli.cli.main import main; main()",
        *[str(a) for a in args],
    ]


# ----------------------------------------------------------------------------- parsing
def test_set_values_are_toml_values_and_bare_words_strings():
    spec = parse_set("geometry.chamber.c1.radii_mm=[10, 10, 4],[12,10,4]")
    assert spec.key == "geometry.chamber.c1.radii_mm"
    assert spec.values == ([10, 10, 4], [12, 10, 4])
    assert parse_set("solver.linear_solver=pcg,direct").values == ("pcg", "direct")
    assert parse_set("geometry.solid=data/a.stl,b.stl").values == ("data/a.stl", "b.stl")
    assert parse_set("mesh.size_mm=3,4.5,1e1").values == (3, 4.5, 10.0)
    assert parse_set('scene.description="a, b",true').values == ("a, b", True)


@pytest.mark.parametrize(
    "option, message",
    [
        ("mesh.size_mm=", "--set mesh.size_mm: empty list of values"),
        ("mesh.size_mm=3,,4", "--set mesh.size_mm: empty value in '3,,4'"),
        ("mesh.size_mm", "expected KEY=V1,V2,..."),
        ("mesh.size_mm=[3,4", "--set mesh.size_mm: cannot read value '[3,4'"),
    ],
)
def test_bad_set_options_are_named(option, message):
    with pytest.raises(SweepError, match=message.replace("[", r"\[").replace(".", r"\.")):
        parse_set(option)


def test_grid_is_every_combination_zip_pairs_lists_of_one_length():
    a, b = parse_set("mesh.size_mm=3,4"), parse_set("material.poisson_ratio=0.3,0.4,0.45")
    grid = combinations([a, b], "grid")
    assert len(grid) == 6 and grid[0] == {"mesh.size_mm": 3, "material.poisson_ratio": 0.3}
    assert grid[1] == {"mesh.size_mm": 3, "material.poisson_ratio": 0.4}
    c = parse_set("material.poisson_ratio=0.3,0.4")
    assert combinations([a, c], "zip") == [
        {"mesh.size_mm": 3, "material.poisson_ratio": 0.3},
        {"mesh.size_mm": 4, "material.poisson_ratio": 0.4},
    ]
    with pytest.raises(
        SweepError,
        match="--zip needs lists of one length: mesh.size_mm has 2, material.poisson_ratio has 3",
    ):
        combinations([a, b], "zip")


def test_keys_reach_sections_chambers_by_name_and_arrays_by_number():
    raw = {
        "geometry": {
            "chamber": [
                {"name": "c1", "ellipsoid": {"center_mm": [0, 0, 0], "radii_mm": [1, 1, 1]}}
            ]
        },
        "jig": [{"region_box_mm": [0, 0, 0, 1, 1, 1]}],
    }
    apply_value(raw, "geometry.chamber.c1.radii_mm", [2, 2, 2])
    apply_value(raw, "jig.1.rotate_deg", 15.0)
    apply_value(raw, "mesh.size_mm", 4.0)
    apply_value(raw, "actuation.pressure_kpa.c1", [0.0, 5.0])
    assert raw["geometry"]["chamber"][0]["ellipsoid"]["radii_mm"] == [2, 2, 2]
    assert raw["jig"][0]["rotate_deg"] == 15.0
    assert raw["mesh"] == {"size_mm": 4.0}
    assert raw["actuation"]["pressure_kpa"] == {"c1": [0.0, 5.0]}
    for key, message in [
        ("mesh.sise_mm", "unknown key 'sise_mm' (did you mean 'size_mm'?)"),
        ("mesk.size_mm", "unknown section [mesk] (did you mean 'mesh'?)"),
        ("geometry.chamber.c9.radii_mm", "no [[geometry.chamber]] 'c9'"),
        ("jig.2.rotate_deg", "no [[jig]] '2'"),
        ("mesh", "name a key"),
    ]:
        with pytest.raises(
            SweepError,
            match=message.replace("[", r"\[")
            .replace("(", r"\(")
            .replace(")", r"\)")
            .replace("?", r"\?"),
        ):
            apply_value(raw, key, 1.0)


def test_variant_names_come_from_values_and_stay_distinct():
    keys = ["geometry.chamber.c1.radii_mm", "geometry.chamber.c2.radii_mm", "mesh.size_mm"]
    labels = short_labels(keys)
    assert labels == {keys[0]: "c1.radii_mm", keys[1]: "c2.radii_mm", keys[2]: "size_mm"}
    name = variant_name({keys[0]: [10, 10, 4.5], keys[1]: [1, 1, 1], keys[2]: 3.0}, labels)
    assert name == "c1.radii_mm=10x10x4.5,c2.radii_mm=1x1x1,size_mm=3"


def test_figures_are_read_from_the_stage_outputs(tmp_path):
    from fruitcli.scene import parse_scene

    scene = parse_scene(PAD + "[sensitivity]\n[bench]\n", tmp_path / "pad.toml")
    (tmp_path / "pad-grid").mkdir()
    (tmp_path / "pad-grid" / "taxels.csv").write_text(
        "# mm\nid,i,j,x_mm,y_mm,z_mm\n0,0,0,0,0,3\n1,0,1,0,12,3\n"
    )
    (tmp_path / "evaluate").mkdir()
    (tmp_path / "evaluate" / "summary.json").write_text(
        json.dumps({"bent-small": {"n": 4, "mean_mm": 2.5, "std_mm": 0.5}})
    )
    (tmp_path / "sensitivity").mkdir()
    (tmp_path / "sensitivity" / "sensitivity.json").write_text(
        json.dumps(
            {
                "summary": {
                    "std": {"max": 1.5, "mean": 1.0},
                    "max_shift": {"max": 9.0, "mean": 4.0},
                    "max_shift_model": {"max": 8.0, "mean": 3.0},
                }
            }
        )
    )
    assert variant_figures(figure_inputs(scene, tmp_path), tmp_path) == {
        "taxels": 2,
        "bent-small_n": 4,
        "bent-small_mean_mm": 2.5,
        "bent-small_std_mm": 0.5,
        "noise_std_max_counts": 1.5,
        "shift_max_counts": 9.0,
        "shift_mean_counts": 4.0,
    }


# ----------------------------------------------------------------------------- bad inputs
@pytest.mark.parametrize(
    "sets, message",
    [
        (["--set", "mesh.sise_mm=3,4"], "unknown key 'sise_mm' (did you mean 'size_mm'?)"),
        (
            ["--set", "mesh.size_mm=3,abc"],
            "variant mesh.size_mm=abc: pad.toml: [mesh].size_mm: "
            "expected a finite number, got 'abc'",
        ),
        (
            ["--set", "material.poisson_ratio=0.3,0.7"],
            "[material].poisson_ratio: expected -1 < nu < 0.5, got 0.7",
        ),
        (["--set", "mesh.size_mm="], "empty list of values"),
        (
            ["--set", "mesh.size_mm=3,4", "--set", "material.poisson_ratio=0.3", "--zip"],
            "--zip needs lists of one length",
        ),
    ],
)
def test_a_bad_key_or_value_stops_the_sweep_before_anything_runs(
    fruit, pad, tmp_path, sets, message
):
    out = tmp_path / "sweep"
    result = fruit("sweep", pad, *sets, "--out", out, "--jobs", 1)
    assert result.exit_code == 2
    assert message in result.output
    assert "Traceback" not in result.output
    assert not out.exists()


def test_a_scheduler_that_does_not_answer_times_out_in_one_line(fruit, pad, tmp_path):
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.perf_counter()
    result = fruit(
        "sweep",
        pad,
        *SETS,
        "--out",
        tmp_path / "s",
        "--scheduler",
        f"tcp://127.0.0.1:{port}",
        "--connect-timeout",
        1,
    )
    assert result.exit_code == 1
    assert (
        f"--scheduler tcp://127.0.0.1:{port}: no Dask scheduler answered within 1 s"
        in result.output
    )
    assert len(result.output.strip().splitlines()) == 1
    assert time.perf_counter() - t0 < 30
    assert not (tmp_path / "s" / "variants").exists()


@pytest.mark.parametrize(
    "address, message",
    [
        (
            "foo",
            "--scheduler foo: not a scheduler address (missing port number in address 'foo'); "
            "expected tcp://host:port",
        ),
        (
            "xyz://1.2.3.4:1",
            "--scheduler xyz://1.2.3.4:1: not a scheduler address (unknown address scheme 'xyz'",
        ),
    ],
)
def test_a_malformed_scheduler_address_is_one_line(pad, tmp_path, address, message):
    proc = subprocess.run(
        fruit_cmd(
            "sweep", pad, "--set", "mesh.size_mm=5", "--out", tmp_path / "s", "--scheduler", address
        ),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"Error: {message}"), proc.stderr


# ----------------------------------------------------------------------------- runs
@pytest.fixture(scope="module")
def serial(pad, tmp_path_factory):
    from click.testing import CliRunner

    from fruitcli.cli.main import cli

    out = tmp_path_factory.mktemp("serial") / "sweep"
    result = CliRunner().invoke(
        cli, ["sweep", str(pad), *SETS, "--out", str(out), "--jobs", "1"], catch_exceptions=False
    )
    assert result.exit_code == 0, result.output
    return out


def test_serial_sweep_writes_one_row_per_variant_and_shares_stages(serial):
    rows = read_rows(serial / "sweep.csv", drop=())
    assert [r["variant"] for r in rows] == [
        "size_mm=4,poisson_ratio=0.3",
        "size_mm=4,poisson_ratio=0.45",
        "size_mm=8,poisson_ratio=0.3",
        "size_mm=8,poisson_ratio=0.45",
    ]
    assert all(r["status"] == "ok" and r["error"] == "" for r in rows)
    assert {r["taxels"] for r in rows} == {"4"} and {r["states"] for r in rows} == {"1"}
    assert rows[0]["tets"] == rows[1]["tets"] != rows[2]["tets"] == rows[3]["tets"]
    for r in rows:
        assert float(r["max_disp_mm"]) > 0 and float(r["state_ms"]) > 0
    # pad-grid ran once for all four, each mesh once for its two variants
    logs = {p.parent.name: p.read_text() for p in (serial / "variants").glob("*/log.txt")}
    assert (
        "tetra: reuse (same inputs as size_mm=4,poisson_ratio=0.3)"
        in logs["size_mm=4,poisson_ratio=0.45"]
    )
    assert sum("pad-grid: run" in t for t in logs.values()) == 1
    assert sum("tetra: run" in t for t in logs.values()) == 2
    assert sum("simulate: run" in t for t in logs.values()) == 4
    md = (serial / "sweep.md").read_text()
    assert "4 variant(s) ran, 0 reused" in md and "3 stage(s) shared" in md
    assert (serial / "sweep.png").stat().st_size > 10_000


def test_a_rerun_reuses_finished_variants_and_runs_only_new_ones(serial, pad, fruit, tmp_path):
    import shutil

    serial = Path(shutil.copytree(serial, tmp_path / "sweep"))  # others compare with it
    before = attempts(serial)
    result = fruit("sweep", pad, *SETS, "--out", serial, "--jobs", 1)
    assert result.exit_code == 0
    assert attempts(serial) == before
    assert "0 variant(s) ran, 4 reused" in (serial / "sweep.md").read_text()
    rows = read_rows(serial / "sweep.csv")
    result = fruit(
        "sweep",
        pad,
        "--set",
        "mesh.size_mm=4,8",
        "--set",
        "material.poisson_ratio=0.3,0.45,0.4",
        "--out",
        serial,
        "--jobs",
        1,
    )
    assert result.exit_code == 0
    now = attempts(serial)
    assert {k: v for k, v in now.items() if k in before} == before
    assert sorted(set(now) - set(before)) == [
        "size_mm=4,poisson_ratio=0.4",
        "size_mm=8,poisson_ratio=0.4",
    ]
    new = read_rows(serial / "sweep.csv")
    assert [r for r in new if r["variant"] in before] == rows


def test_a_failing_variant_is_a_row_and_the_sweep_goes_on(fruit, pad, tmp_path):
    out = tmp_path / "sweep"
    result = fruit(
        "sweep",
        pad,
        "--set",
        "jig.1.region_box_mm=[14, -21, -1, 21, 21, 4],[100, 100, 100, 101, 101, 101]",
        "--out",
        out,
        "--jobs",
        1,
    )
    assert result.exit_code == 0
    ok, bad = read_rows(out / "sweep.csv")
    assert ok["status"] == "ok" and ok["error"] == ""
    assert bad["status"] == "failed"
    assert bad["error"].startswith("simulate: ") and "region_box_mm" in bad["error"]
    assert "\n" not in bad["error"]
    assert "1 of 2 variants failed" in result.output
    # a rerun tries the failed variant again, not the finished one
    before = attempts(out)
    fruit(
        "sweep",
        pad,
        "--set",
        "jig.1.region_box_mm=[14, -21, -1, 21, 21, 4],[100, 100, 100, 101, 101, 101]",
        "--out",
        out,
        "--jobs",
        1,
    )
    after = attempts(out)
    assert after[ok["variant"]] == before[ok["variant"]]
    assert after[bad["variant"]] == before[bad["variant"]] + 1


def test_a_shared_stage_that_fails_runs_once_and_fails_the_variants_needing_it(
    fruit, pad, tmp_path
):
    out = tmp_path / "sweep"
    result = fruit(
        "sweep",
        pad,
        "--set",
        "mesh.min_quality=0.99",
        "--set",
        "material.poisson_ratio=0.3,0.45",
        "--out",
        out,
        "--jobs",
        1,
    )
    assert result.exit_code == 1
    rows = read_rows(out / "sweep.csv")
    assert [r["status"] for r in rows] == ["failed", "failed"]
    assert rows[0]["error"] == rows[1]["error"]
    assert rows[0]["error"].startswith("tetra: ") and "min_quality" in rows[0]["error"]
    assert f"every variant failed (first: {rows[0]['error']})" in result.output
    starts = [
        ln.split(" pid=")[0]
        for p in (out / "variants").glob("*/attempts.log")
        for ln in p.read_text().splitlines()
    ]
    assert sorted(starts) == ["stage pad-grid", "stage tetra"]  # no variant task ran
    assert not (out / "sweep.png").exists()


def _kill_first_variant(out: Path, proc: subprocess.Popen, timeout_s: float = 300) -> str:
    """Wait until a variant task starts, SIGKILL the process running it; its name."""
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < timeout_s:
        for log in (out / "variants").glob("*/attempts.log"):
            lines = [ln for ln in log.read_text().splitlines() if ln.startswith("variant")]
            if lines:
                pid = int(lines[0].split("pid=")[1].split()[0])
                os.kill(pid, signal.SIGKILL)
                return log.parent.name
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.01)
    raise AssertionError("no variant started")


@pytest.mark.slow
def test_jobs_2_with_a_worker_killed_during_a_variant_gives_the_serial_sweep_csv(
    serial, pad, tmp_path
):
    out = tmp_path / "sweep"
    proc = subprocess.Popen(
        fruit_cmd("sweep", pad, *SETS, "--out", out, "--jobs", 2),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    killed = _kill_first_variant(out, proc)
    stdout, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 0, stderr
    assert attempts(out)[killed] == 2
    assert read_rows(out / "sweep.csv") == read_rows(serial / "sweep.csv")
    assert "sweep: 4 variants on 2 local processes" in stderr
    assert "sweep: 4/4 variants" in stderr


# ----------------------------------------------------------------------------- Dask
@pytest.fixture(scope="module")
def cluster():
    import distributed  # the cluster extra, installed by make test

    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as c:
        yield c


@pytest.mark.slow
def test_a_dask_cluster_gives_the_serial_sweep_csv(serial, pad, tmp_path, cluster, fruit):
    out = tmp_path / "sweep"
    result = fruit("sweep", pad, *SETS, "--out", out, "--scheduler", cluster.scheduler_address)
    assert result.exit_code == 0, result.output
    assert read_rows(out / "sweep.csv") == read_rows(serial / "sweep.csv")
    hosts = {
        ln.split("pid=")[1].split()[0]
        for p in (out / "variants").glob("*/attempts.log")
        for ln in p.read_text().splitlines()
    }
    assert str(os.getpid()) not in hosts  # the variants ran on the workers


@pytest.mark.slow
def test_a_dask_worker_killed_during_a_variant_the_sweep_completes(serial, pad, tmp_path, cluster):
    out = tmp_path / "sweep"
    proc = subprocess.Popen(
        fruit_cmd("sweep", pad, *SETS, "--out", out, "--scheduler", cluster.scheduler_address),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    killed = _kill_first_variant(out, proc)
    stdout, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 0, stderr
    assert attempts(out)[killed] == 2
    assert read_rows(out / "sweep.csv") == read_rows(serial / "sweep.csv")


def test_workers_that_cannot_see_out_are_refused(pad, tmp_path, cluster, monkeypatch):
    from fruitcli.studies import executors

    monkeypatch.setattr(executors, "see_probe", _blind_probe)
    with pytest.raises(executors.FruitError, match=r"not visible to (\d) of \1 workers"):
        executors.open_executor(scheduler=cluster.scheduler_address, out_dir=tmp_path / "o")


def _blind_probe(path, token):
    """A worker that looks for the probe file somewhere else (another file system)."""
    from fruitcli.studies.executors import code_hash

    return Path(path + ".elsewhere").exists(), socket.gethostname(), code_hash()


def test_studies_run_their_cases_on_a_dask_cluster(cluster):
    from fruitcli.studies.parallel import run_cases
    from fruitcli.studies.stability import default_cases, run_case

    cases = [c for c in default_cases() if c.group == "jig"][:2]
    serial = run_cases(run_case, cases, jobs=1)
    done = []
    on_dask = run_cases(
        run_case,
        cases,
        scheduler=cluster.scheduler_address,
        progress=lambda n, total: done.append((n, total)),
    )
    assert done == [(1, 2), (2, 2)]
    for s, d in zip(serial, on_dask, strict=True):
        for key in ("status", "iterations", "residual", "max_disp_mm", "min_det_f"):
            assert s[key] == d[key]


@pytest.mark.slow
def test_the_runtime_study_on_a_dask_cluster_gives_the_serial_rows(pad, tmp_path, cluster, fruit):
    scene = tmp_path / "pad8.toml"  # coarser: the study meshes 16 to 6.4 mm
    scene.write_text(PAD.replace("size_mm = 5.0", "size_mm = 8.0"))
    rows = {}
    for where in (["--jobs", 1], ["--scheduler", cluster.scheduler_address]):
        out = tmp_path / where[0].strip("-")
        result = fruit("-q", "study", "runtime", scene, "--out", out, *where)
        assert result.exit_code == 0, result.output
        fem = json.loads((out / "runtime.json").read_text())["fem"]
        rows[where[0]] = [
            {k: v for k, v in r.items() if k not in ("state_ms", "simulate_s", "pareto")}
            for r in fem
        ]
    # equal, floats to 1e-6 relative (kept from when MKL PARDISO's threads summed in a
    # run-dependent order; it runs on one thread now)
    assert len(rows["--jobs"]) == len(rows["--scheduler"])
    for a, b in zip(rows["--jobs"], rows["--scheduler"], strict=True):
        assert a.keys() == b.keys()
        for k in a:
            if isinstance(a[k], float):
                assert a[k] == pytest.approx(b[k], rel=1e-6, abs=1e-6), k
            else:
                assert a[k] == b[k], k
    assert len(rows["--jobs"]) >= 2 and all(r["status"] == "ok" for r in rows["--jobs"])


def _die(arg, deps):
    os.kill(os.getpid(), signal.SIGKILL)


def _after(arg, deps):
    return arg, dict(deps)


def test_a_task_whose_local_worker_always_dies_is_given_up_after_3_attempts():
    from fruitcli.studies.executors import MAX_ATTEMPTS, LocalPool, Task, run_graph

    pool = LocalPool(2)
    try:
        tasks = {"dies": Task(_die, None), "next": Task(_after, 7, deps=("dies",))}
        results = run_graph(pool, tasks, on_lost=lambda key, message: f"lost: {message}")
    finally:
        pool.close()
    assert MAX_ATTEMPTS == 3 and tasks["dies"].attempts == 3
    assert results["dies"] == "lost: its worker process died 3 time(s)"
    assert results["next"] == (7, {"dies": "lost: its worker process died 3 time(s)"})


def test_skin_figures_are_the_crossings_in_the_scenes_counts(tmp_path):
    """A sweep row's crossing figures from `fruit skin`'s summary.json: the contact counts
    and the bent pad's shift rescaled to the scene's [skin].counts_per_ff, the margin the
    threshold less the larger bend shift; nothing without a summary."""
    import json

    from fruitcli.scene import parse_scene
    from fruitcli.studies.sweep_run import figure_inputs, skin_figures

    summary = {
        "c0_ff": 850.0,
        "counts_per_ff": 0.5,
        "objects": {"small": {"contact_counts": 22.0}, "finger": {"contact_counts": 64.0}},
        "deformation_shift_counts": {"bend_x": [0.0, -2.0, -4.0], "bend_y": [0.0, 5.0, 10.0]},
    }
    path = tmp_path / "summary.json"
    path.write_text(json.dumps(summary))
    fitted = parse_scene('[skin]\nmodel = "electrostatic"\n', tmp_path / "a.toml")
    assert skin_figures(figure_inputs(fitted, tmp_path), path) == {
        "c0_ff": 850.0,
        "counts_per_ff": 0.5,
        "contact_counts_small": 22.0,
        "contact_counts_finger": 64.0,
        "bend_shift_max_counts": 10.0,
        "bend_margin_counts": 10.0,
    }
    given = parse_scene(
        '[skin]\nmodel = "electrostatic"\ncounts_per_ff = 1.0\n'
        "[detection]\nthreshold_counts = 25\n",
        tmp_path / "b.toml",
    )
    out = skin_figures(figure_inputs(given, tmp_path), path)
    assert out["contact_counts_small"] == pytest.approx(44.0)
    assert out["bend_shift_max_counts"] == pytest.approx(20.0)
    assert out["bend_margin_counts"] == pytest.approx(5.0)
    assert skin_figures(figure_inputs(given, tmp_path), tmp_path / "none.json") == {}
