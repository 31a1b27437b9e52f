"""Error-against-run-time study: Pareto front, errors against the finest setting."""

from __future__ import annotations

import numpy as np

from fruitcli.studies.runtime import add_errors, default_reason, fem_cases, pareto


def test_pareto_front_keeps_only_undominated_points():
    pts = [(1.0, 5.0), (2.0, 2.0), (3.0, 3.0), (4.0, 1.0), (2.0, 2.0)]
    assert pareto(pts) == [True, True, False, True, True]


def test_errors_are_measured_against_the_finest_setting():
    base = np.zeros((3, 3))
    rows = [
        {
            "setting": "coarse",
            "size_mm": 8.0,
            "tolerance": 1e-6,
            "status": "ok",
            "taxels": (base + [0.3, 0.4, 0.0]).tolist(),
        },
        {
            "setting": "fine",
            "size_mm": 4.0,
            "tolerance": 1e-6,
            "status": "ok",
            "taxels": base.tolist(),
        },
        {"setting": "broken", "size_mm": 2.0, "tolerance": 1e-6, "status": "failed: x"},
    ]
    add_errors(rows)
    assert rows[1]["reference"] and rows[1]["taxel_err_mean_mm"] == 0.0
    assert np.isclose(rows[0]["taxel_err_mean_mm"], 0.5)
    assert "taxel_err_mean_mm" not in rows[2]
    assert all("taxels" not in r for r in rows)


def test_cases_sweep_size_tolerance_cap_and_solver():
    cases = fem_cases(5.0)
    sizes = {c.size_mm for c in cases}
    assert {10.0, 5.0, 4.0} <= sizes
    assert {c.linear_solver for c in cases} >= {"pcg", "direct"}
    assert any(c.max_iterations < 25 for c in cases)
    assert len({c.name for c in cases}) == len(cases)
    # the paper's model and the other elements, at the default size, against the scene's
    elements = {(c.element, c.material) for c in cases if c.element is not None}
    assert ("p1", "corotational") in elements and ("p2-pure", "neo-hookean") in elements
    assert all(c.size_mm == 5.0 for c in cases if c.element is not None)


def test_default_reason_uses_the_measured_row():
    rows = [{"setting": "size 5 mm", "status": "ok", "taxel_err_mean_mm": 0.07, "state_ms": 120.0}]
    text = default_reason(rows, "size 5 mm")
    assert "0.070 mm against the finest setting, at 120 ms per state: below" in text
    rows = [
        {"setting": "size 5 mm", "status": "ok", "taxel_err_mean_mm": 0.12, "state_ms": 24.0},
        {
            "setting": "size 4 mm",
            "status": "ok",
            "taxel_err_mean_mm": 0.0,
            "state_ms": 37.0,
            "reference": True,
        },
    ]
    text = default_reason(rows, "size 5 mm")
    assert "0.120 mm against the finest setting, at 24 ms per state: above" in text
    assert "the finest setting (size 4 mm) takes 37 ms per state" in text
    assert "finer settings cost time for no difference" not in text
