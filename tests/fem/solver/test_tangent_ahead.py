"""A load step's first evaluation brings the element tangents along (`newton.NewtonStep.
evaluate`): on a hollow cube of quadratic neo-Hookean tets under 6, 9 then 12 kPa, the
same iterates bit for bit as with the tangent in a loop of its own, in fewer element
loops."""

import numpy as np

from fruitcli.fem.solver import newton
from fruitcli.fem.solver.options import SolverOptions
from fruitcli.fem.solver.state import solve_state
from fruitcli.fem.state_load import Load
from tests.fem.solver.test_displacement_tolerance import hollow_cube


def three_states(m):
    """(states, element loops evaluated, of them with the tangent)."""
    calls = []
    evaluate = m.evaluate

    def counted(x, tangent=False, **kw):
        calls.append(tangent)
        return evaluate(x, tangent, **kw)

    m.evaluate = counted
    solver = m.make_solver("pcg")
    options = SolverOptions(tolerance=1e-9)
    states, prev = [], None
    for kpa in (6.0, 9.0, 12.0):
        load = Load.pressures([kpa])
        s = solve_state(
            m,
            load,
            x_start=None if prev is None else states[-1].x,
            load_start=prev,
            pressure_start=None if prev is None else states[-1].pressure_kpa,
            solver=solver,
            options=options,
        )
        states.append(s)
        prev = load
    return states, len(calls), sum(calls)


def test_the_tangent_at_the_start_changes_no_iterate_and_saves_element_loops(monkeypatch):
    ahead, loops_ahead, _ = three_states(hollow_cube("p2"))
    evaluate = newton.NewtonStep.evaluate  # never ahead: each tangent in a loop of its own
    monkeypatch.setattr(newton.NewtonStep, "evaluate", lambda s, x, p, t=False: evaluate(s, x, p))
    plain, loops_plain, _ = three_states(hollow_cube("p2"))
    for a, b in zip(ahead, plain, strict=True):
        assert np.array_equal(a.x, b.x) and np.array_equal(a.pressure_kpa, b.pressure_kpa)
        assert a.iterations == b.iterations
    assert loops_ahead < loops_plain
