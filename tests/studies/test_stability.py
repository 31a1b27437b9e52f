"""The stability study: rows for every case, named failures, no NaN, parallel == serial."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fruitcli.fem.meshing.grid import structured_box, structured_box_with_cavity
from fruitcli.fem.meshing.topology import boundary_faces
from fruitcli.studies.parallel import run_cases
from fruitcli.studies.stability import Case, default_cases, run_case


def test_box_mesh_is_conforming_and_fills_the_box():
    from fruitcli.fem.elements.tet4 import signed_volumes

    nodes, tets = structured_box((0.0, 0.0, 0.0), (2.0, 3.0, 4.0), (2, 3, 4))
    vol = np.abs(signed_volumes(nodes, tets))
    assert np.isclose(vol.sum(), 24.0)
    # closed surface: 2 triangles per boundary cell face
    assert len(boundary_faces(nodes, tets)) == 2 * 2 * (2 * 3 + 3 * 4 + 2 * 4)


def test_hollow_box_cavity_is_closed():
    nodes, tets, cavity = structured_box_with_cavity(
        (0.0,) * 3, (30.0,) * 3, (6, 6, 6), (10.0,) * 3, (20.0,) * 3
    )
    assert len(cavity) == 6 * 4 * 2  # 6 faces of 2 x 2 cells, 2 triangles each
    edges = np.sort(
        np.concatenate([cavity[:, [0, 1]], cavity[:, [1, 2]], cavity[:, [2, 0]]]), axis=1
    )
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)


def test_every_case_gives_a_finite_row_or_a_named_failure():
    cases = [
        Case("E", "E = 1e+06 kPa", "beam_gravity", E_kpa=1e6),
        Case("sliver", "one sliver tet", "sliver"),
        Case("jig", "k = 1e+06 N/mm", "jig", stiffness_n_per_mm=1e6),
    ]
    rows = [run_case(c) for c in cases]
    assert rows[0]["status"] == "converged"
    assert rows[0]["tip_deflection_mm"] > 0
    assert rows[1]["status"].startswith("failed: mesh: tet")
    assert "sliver" in rows[1]["status"] and "\n" not in rows[1]["status"]
    for r in rows:
        for key in ("residual", "max_disp_mm", "min_det_f"):
            assert r[key] is None or math.isfinite(r[key])


def test_stiff_response_scales_as_one_over_E():
    a = run_case(Case("E", "a", "beam_gravity", E_kpa=1e4))
    b = run_case(Case("E", "b", "beam_gravity", E_kpa=1e6))
    ratio = a["tip_deflection_mm"] / b["tip_deflection_mm"]
    assert abs(ratio - 100.0) < 0.5


def test_parallel_equals_serial():
    cases = [c for c in default_cases() if c.group in ("jig",)][:3]
    serial = run_cases(run_case, cases, jobs=1)
    parallel = run_cases(run_case, cases, jobs=2)
    for s, p in zip(serial, parallel, strict=True):
        for key in ("status", "iterations", "residual", "max_disp_mm", "min_det_f"):
            assert s[key] == p[key]


@pytest.mark.slow
def test_realistic_sphere_past_its_limit_is_a_named_failure():
    """The gmsh thick sphere at 2000 kPa: a failed row naming the limit (not a Newton
    failure after minutes)."""
    case = next(c for c in default_cases() if c.name == "p = 2000 kPa (sphere)")
    row = run_case(case)
    assert row["status"].startswith(
        "failed: [actuation].pressure_kpa.cavity: 2000 kPa is past this chamber's limit pressure"
    )
    assert "\n" not in row["status"]


@pytest.mark.slow
def test_the_default_fruit_sucked_past_its_collapse_is_a_named_failure():
    """The default Fruit's chamber c1 at -500 kPa: a failed row naming the collapse of
    the scene key's chamber within the row's budget, the other chambers at rest."""
    case = next(c for c in default_cases() if c.name == "p = -500 kPa (fruit)")
    row = run_case(case)
    assert row["status"].startswith(
        "failed: [actuation].pressure_kpa.c1: -500 kPa is past this chamber's collapse"
    )
    assert "\n" not in row["status"]


def test_group_option_runs_only_those_cases(tmp_path):
    import json

    from click.testing import CliRunner

    from fruitcli.cli.main import cli

    out = tmp_path / "s"
    result = CliRunner().invoke(
        cli, ["study", "stability", "--group", "jig", "--out", str(out), "--jobs", "1"]
    )
    assert result.exit_code == 0, result.output
    rows = json.loads((out / "stability.json").read_text())
    assert [r["group"] for r in rows] == ["jig"] * 5
    assert (out / "stability.md").read_text().splitlines()[2].startswith("Run 20")
    result = CliRunner().invoke(cli, ["study", "stability", "--group", "nope", "--out", str(out)])
    assert result.exit_code == 2
    assert "'nope' is not a group (groups: E; nu; pressure;" in result.output
