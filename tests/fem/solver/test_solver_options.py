"""Solver options that would make a state diverge, stop before solving or never end are
refused at once, with one line naming the [solver] key."""

import math

import pytest

from fruitcli.errors import SolverError
from fruitcli.fem.solver.options import SolverOptions


@pytest.mark.parametrize(
    "key, value, expected",
    [
        ("tolerance", 0.0, "0 < tolerance < 1"),
        ("tolerance", -1e-6, "0 < tolerance < 1"),
        ("tolerance", 1.0, "0 < tolerance < 1"),
        ("tolerance", math.nan, "0 < tolerance < 1"),
        ("max_iterations", 0, ">= 1"),
        ("max_subdivisions", -1, ">= 0"),
        ("load_steps", 0, ">= 1"),
        ("displacement_tolerance_mm", -1e-4, ">= 0"),
        ("max_seconds", -1.0, "a time budget > 0 s (0: none)"),
        ("max_seconds", math.inf, "a time budget > 0 s (0: none)"),
    ],
)
def test_bad_option_is_one_line_naming_the_key(key, value, expected):
    with pytest.raises(SolverError) as err:
        SolverOptions(**{key: value})
    message = str(err.value)
    assert message.startswith(f"[solver].{key}: expected {expected}, got ")
    assert "\n" not in message


def test_the_defaults_and_no_budget_are_accepted():
    assert SolverOptions().max_seconds == 0.0  # 0: no time budget
    assert SolverOptions(max_subdivisions=0, displacement_tolerance_mm=0.0).tolerance == 1e-6
