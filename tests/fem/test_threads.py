"""The element loops over several threads (`fruitcli.fem.threads`, numba's prange): the
nodes' sums are gathered in element order, so one thread and two give the same bits;
the choice of threads from what else runs."""

import numba
import numpy as np
import pytest

from fruitcli.fem import threads
from fruitcli.fem.continuum import ContinuumModel
from fruitcli.fem.corotational_model import Model
from fruitcli.fem.elements.quadratic import quadratic_mesh
from fruitcli.fem.materials.build import material
from fruitcli.fem.meshing.grid import structured_box, structured_box_with_cavity
from fruitcli.fem.solver.linsolve import TangentSolver
from fruitcli.fem.solver.options import SolverOptions
from fruitcli.fem.solver.state import solve_state
from fruitcli.fem.state_load import Load

pytestmark = pytest.mark.skipif(
    numba.config.NUMBA_NUM_THREADS < 2, reason="one thread only on this machine"
)


@pytest.fixture
def fixed_threads():
    """Threads set by the test, not chosen from the load; restored afterwards."""
    before = numba.get_num_threads()
    threads.AUTO = False
    yield
    threads.AUTO = True
    numba.set_num_threads(before)


def solve_hollow_cube(n_threads: int):
    """A hollow cube (1,600 tets, more than the loops' 64 blocks) under 6 kPa, then
    9 kPa from there, on n_threads; the nodes of both states."""
    numba.set_num_threads(n_threads)
    nodes, tets, cav = structured_box_with_cavity(
        [0, 0, 0], [12, 12, 12], (10, 10, 4), [3, 3, 3], [9, 9, 9]
    )
    m = Model.from_arrays(
        nodes,
        tets,
        100.0,
        0.49,
        chambers={"c": cav},
        fixed_nodes=np.flatnonzero(nodes[:, 2] == 0.0),
    )
    solver = TangentSolver(m)
    a = solve_state(m, Load.pressures([6.0]), solver=solver, options=SolverOptions(tolerance=1e-8))
    b = solve_state(
        m,
        Load.pressures([9.0]),
        x_start=a.x,
        load_start=Load.pressures([6.0]),
        pressure_start=a.pressure_kpa,
        solver=solver,
        options=SolverOptions(tolerance=1e-8),
    )
    assert len(m.tets) > 64
    return a.x, b.x


def test_paper_model_gives_the_same_bits_on_one_thread_and_two(fixed_threads):
    """Forces, products and rotations summed per node in element order: two states of
    the corotational model solved on one thread and on two are equal to the last bit."""
    one = solve_hollow_cube(1)
    two = solve_hollow_cube(2)
    for x1, x2 in zip(one, two, strict=True):
        assert np.array_equal(x1, x2)


def test_hyperelastic_loop_gives_the_same_bits_on_one_thread_and_two(fixed_threads):
    """The quadratic element loop: energy, forces and element tangents at a distorted
    configuration are equal to the last bit on one thread and on two."""
    nodes, tets = structured_box([0, 0, 0], [4, 4, 2], (6, 6, 3))
    nodes, conn, _ = quadratic_mesh(nodes, tets, [])
    m = ContinuumModel.from_arrays(
        nodes,
        conn,
        material("neo-hookean", 100.0, 0.49),
        "p2",
        fixed_nodes=np.flatnonzero(nodes[:, 2] == 0.0),
    )
    x = nodes + 0.03 * np.random.default_rng(3).standard_normal(nodes.shape)
    out = []
    for n in (1, 2):
        numba.set_num_threads(n)
        out.append(m.evaluate(x, tangent=True))
    (f1, e1, j1, k1), (f2, e2, j2, k2) = out
    assert len(conn) > 64
    assert e1 == e2
    assert np.array_equal(f1, f2) and np.array_equal(j1, j2) and np.array_equal(k1, k2)


def test_threads_chosen_from_what_else_runs(monkeypatch):
    """One thread when other processes keep more than BUSY_CORES busy, every core when
    the machine is free (a choice holds for KEEP_S), and the caller's choice when AUTO
    is off; the measurement itself is a number of cores between 0 and the machine's."""
    before = numba.get_num_threads()
    try:
        busy = threads.others_busy_cores(0.05)
        assert busy is None or 0.0 <= busy <= (numba.config.NUMBA_NUM_THREADS + 1)
        monkeypatch.setattr(threads, "others_busy_cores", lambda window_s=0.1: 1.0)
        monkeypatch.setattr(threads, "_CHOICE", (-1e9, 0))
        assert threads.choose_element_threads() == 1 == numba.get_num_threads()
        monkeypatch.setattr(threads, "others_busy_cores", lambda window_s=0.1: 0.0)
        assert threads.choose_element_threads() == 1  # the choice holds for KEEP_S
        monkeypatch.setattr(threads, "_CHOICE", (-1e9, 0))
        assert threads.choose_element_threads() == numba.config.NUMBA_NUM_THREADS
        numba.set_num_threads(1)
        monkeypatch.setattr(threads, "AUTO", False)
        assert threads.choose_element_threads() == 1
    finally:
        numba.set_num_threads(before)
