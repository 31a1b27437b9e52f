"""Newton's displacement tolerance (`[solver] displacement_tolerance_mm`): a state may
stop once the kept factor estimates the correction left below it. On a hollow cube
(nu = 0.49) under 6 then 9 kPa: fewer Newton steps, every node within the tolerance of
the tightly converged state; a volume-controlled chamber still meets its volume; CG
started from the estimate's solve takes the same iterations to the same solution as CG
solving again."""

import numpy as np
import pytest

from fruitcli.fem.continuum import ContinuumModel
from fruitcli.fem.corotational_model import Model
from fruitcli.fem.elements.quadratic import quadratic_mesh
from fruitcli.fem.materials.build import material
from fruitcli.fem.meshing.grid import structured_box_with_cavity
from fruitcli.fem.solver.options import SolverOptions
from fruitcli.fem.solver.state import solve_state
from fruitcli.fem.state_load import Load


def hollow_cube(element: str):
    """A 12 mm cube with a 6 mm cavity, base fixed, E = 100 kPa, nu = 0.49: linear
    corotational tets or quadratic neo-Hookean ones."""
    nodes, tets, cav = structured_box_with_cavity(
        [0, 0, 0], [12, 12, 12], (6, 6, 3), [3, 3, 3], [9, 9, 9]
    )
    fixed = np.flatnonzero(nodes[:, 2] == 0.0)
    if element == "p1":
        return Model.from_arrays(nodes, tets, 100.0, 0.49, chambers={"c": cav}, fixed_nodes=fixed)
    nodes, conn, walls = quadratic_mesh(nodes, tets, [cav])
    return ContinuumModel.from_arrays(
        nodes,
        conn,
        material("neo-hookean", 100.0, 0.49),
        "p2",
        chambers={"c": walls[0]},
        fixed_nodes=fixed,
    )


def two_states(m, options):
    """6 kPa from rest, then 9 kPa from there with the same solver."""
    solver = m.make_solver("pcg")
    a = solve_state(m, Load.pressures([6.0]), solver=solver, options=options)
    b = solve_state(
        m,
        Load.pressures([9.0]),
        x_start=a.x,
        load_start=Load.pressures([6.0]),
        pressure_start=a.pressure_kpa,
        solver=solver,
        options=options,
    )
    return a, b


@pytest.mark.parametrize("element", ["p1", "p2"])
def test_displacement_tolerance_saves_newton_steps_within_it(element):
    """At tolerance 1e-6 with a displacement tolerance of 1e-3 mm (nodes move up to
    0.35-0.45 mm): fewer Newton steps than without, every node within 1e-3 mm of the
    state converged to 1e-12."""
    m = hollow_cube(element)
    exact = two_states(m, SolverOptions(tolerance=1e-12))
    plain = two_states(m, SolverOptions(tolerance=1e-6))
    early = two_states(m, SolverOptions(tolerance=1e-6, displacement_tolerance_mm=1e-3))
    assert sum(s.iterations for s in early) < sum(s.iterations for s in plain)
    for ref, state in zip(exact, early, strict=True):
        assert np.abs(state.x - ref.x).max() <= 1e-3


def test_volume_controlled_chamber_ignores_the_displacement_tolerance():
    """A chamber grown by 5 mm^3 meets that volume to 1e-6 of its rest volume even with
    a displacement tolerance of 1 m: the estimate does not bound the volume error."""
    m = hollow_cube("p1")
    load = Load(
        pressure_kpa=np.zeros(1),
        volume_growth_mm3=np.array([5.0]),
        volume_controlled=np.array([True]),
    )
    res = solve_state(m, load, options=SolverOptions(tolerance=1e-6, displacement_tolerance_mm=1e3))
    target = m.chamber_rest_volume_mm3[0] + 5.0
    assert abs(res.chamber_volume_mm3[0] - target) <= 1e-6 * m.chamber_rest_volume_mm3[0]


@pytest.mark.parametrize("element", ["p1", "p2"])
def test_cg_from_the_kept_estimate_solves_as_cg_afresh(element):
    """solve(r) right after estimate(r) starts CG from the estimate's solve: the same CG
    iterations and the same solution as a solver that solves afresh (to round-off: the
    dot products' rounding depends on the arrays' alignment); after a new factorization
    the estimate is not used (it belongs to the old factor)."""
    m = hollow_cube(element)
    state = solve_state(m, Load.pressures([6.0]), options=SolverOptions(tolerance=1e-8))
    r = np.random.default_rng(0).standard_normal(len(m.pattern.free))

    def stale_solver():
        solver = m.make_solver("pcg")
        solver.update(*prepare(m, m.rest))  # factor at rest ...
        solver.update(*prepare(m, state.x))  # ... tangent at the state: CG needed
        solver.rtol = 1e-10
        return solver

    with_estimate, plain = stale_solver(), stale_solver()
    z = with_estimate.estimate(r)
    assert z is not None and with_estimate.estimated[0] is r
    a, b = with_estimate.solve(r), plain.solve(r)
    assert with_estimate.stats["cg_iterations"] == plain.stats["cg_iterations"] > 1
    assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()
    with_estimate.estimated = (r, with_estimate.stats["factorizations"] - 1, 0 * z)
    assert np.abs(with_estimate.solve(r) - b).max() <= 1e-12 * np.abs(b).max()


def prepare(m, x):
    """The arguments of a solver's `update` at configuration x (the model's own)."""
    if isinstance(m, ContinuumModel):
        return (x,)
    f, rot, _ = m.kinematics(x)
    return rot, f
