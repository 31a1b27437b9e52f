"""Closed-form cases on structured meshes (no gmsh): cantilever under gravity, springs
rotating a free body, H as the volume gradient, pressure/volume control, extremes."""

import numpy as np
import pytest

from fruitcli.errors import MeshError, SolverError
from fruitcli.fem.corotational_model import Model
from fruitcli.fem.loads import pressure
from fruitcli.fem.loads.springs import Jig, nodes_in_box, rotation_matrix
from fruitcli.fem.meshing.grid import structured_box, structured_box_with_cavity
from fruitcli.fem.solver.options import SolverOptions
from fruitcli.fem.solver.state import solve_state
from fruitcli.fem.state_load import Load
from fruitcli.fem.units import body_force_mn_mm3

RNG = np.random.default_rng(3)
L, B, H = 100.0, 10.0, 10.0


def cantilever_tip(cells, E=1e5, nu=0.3, rho=1000.0, solver="pcg"):
    nodes, tets = structured_box([0, 0, 0], [L, B, H], cells)
    fixed = np.flatnonzero(nodes[:, 0] == 0.0)
    m = Model.from_arrays(
        nodes, tets, E, nu, density_kg_m3=rho, gravity_m_s2=[0, 0, -9.81], fixed_nodes=fixed
    )
    res = solve_state(m, Load.pressures([]), options=SolverOptions(linear_solver=solver))
    tip = nodes[:, 0] == L
    return -res.displacement_mm[tip, 2].mean(), m


def beam_theory(E=1e5, nu=0.3, rho=1000.0):
    """Euler-Bernoulli q L^4 / 8EI plus Timoshenko's shear q L^2 / (2 kappa G A)."""
    q = -body_force_mn_mm3(rho, [0, 0, -9.81])[2] * B * H  # mN/mm
    inertia = B * H**3 / 12.0
    kappa = 10 * (1 + nu) / (12 + 11 * nu)
    g = E / (2 * (1 + nu))
    return q * L**4 / (8 * E * inertia) + q * L**2 / (2 * kappa * g * B * H)


def test_body_force_units():
    """1000 kg/m^3 * 9.81 m/s^2 = 9810 N/m^3 = 9.81e-6 N/mm^3 = 9.81e-3 mN/mm^3."""
    assert body_force_mn_mm3(1000.0, [0, 0, -9.81])[2] == pytest.approx(-9.81e-3)


def test_cantilever_converges_from_below_to_timoshenko():
    """Linear tets are too stiff in bending: tip deflections increase with refinement,
    stay below beam theory, and the finest (40x4x4 cells) is within 18 % (measured
    0.85, 0.126 vs 0.1487 mm)."""
    exact = beam_theory()
    tips = [cantilever_tip(c)[0] for c in [(10, 1, 1), (20, 2, 2), (40, 4, 4)]]
    assert tips[0] < tips[1] < tips[2] < exact
    assert tips[2] > 0.82 * exact
    # the error shrinks by at least a factor 1.5 per halving of the cell size
    errors = [exact - t for t in tips]
    assert errors[1] < errors[0] / 1.5 and errors[2] < errors[1] / 1.5


def test_springs_rotate_free_body_to_rotated_rest_shape():
    """A free bar whose end region is pulled to a 30-degree rotated target ends at the
    rotated rest shape everywhere (no spurious strain), to 1e-6 mm."""
    nodes, tets = structured_box([0, 0, 0], [40, 8, 8], (10, 2, 2))
    region = nodes_in_box(nodes, [-1, -1, -1, 10.5, 9, 9])
    jig = Jig(
        region,
        1e4,
        rotate_deg=30.0,
        axis=(0.0, 1.0, 1.0),
        pivot_mm=(20.0, 4.0, 4.0),
        translate_mm=(1.0, -2.0, 0.5),
    )
    m = Model.from_arrays(nodes, tets, 100.0, 0.3, jigs=[jig])
    res = solve_state(
        m,
        Load.pressures([]),
        options=SolverOptions(tolerance=1e-10, load_steps=3, max_iterations=60),
    )
    q = rotation_matrix((0.0, 1.0, 1.0), 30.0)
    target = (nodes - [20.0, 4.0, 4.0]) @ q.T + [20.0, 4.0, 4.0] + [1.0, -2.0, 0.5]
    assert np.abs(res.x - target).max() < 1e-6
    assert res.min_det_f == pytest.approx(1.0, abs=1e-9)


def sphere_surface():
    import trimesh

    s = trimesh.creation.icosphere(2, 5.0)
    return np.asarray(s.vertices) + [1.0, 2.0, 3.0], np.asarray(s.faces)


def test_volume_gradient_identities():
    """H equals the finite-difference volume gradient; H.(translation) = 0,
    H.(rotation) = 0 and H.(eps x) = 3 eps V."""
    x, tris = sphere_surface()
    x = x + 0.2 * RNG.normal(size=x.shape)
    h = pressure.volume_gradient(x, tris)
    v = pressure.cavity_volume(x, tris)
    d = RNG.normal(size=x.shape)
    eps = 1e-6
    fd = pressure.cavity_volume(x + eps * d, tris) - pressure.cavity_volume(x - eps * d, tris)
    assert fd / (2 * eps) == pytest.approx(np.sum(h * d), rel=1e-7)
    assert abs(np.sum(h * [0.3, -1.0, 2.0])) < 1e-10 * v
    omega = np.array([0.2, -0.5, 0.9])
    assert abs(np.sum(h * np.cross(omega, x))) < 1e-10 * v
    assert np.sum(h * x) == pytest.approx(3 * v, rel=1e-12)


def cavity_model(E=100.0, nu=0.3, **kw):
    nodes, tets, cav = structured_box_with_cavity(
        [0, 0, 0], [12, 12, 12], (6, 6, 6), [4, 4, 4], [8, 8, 8]
    )
    fixed = np.flatnonzero(nodes[:, 2] == 0.0)
    return Model.from_arrays(nodes, tets, E, nu, fixed_nodes=fixed, chambers={"c": cav}, **kw)


def test_cavity_pressure_and_volume_control_agree():
    """Volume control reaching the growth found under 4 kPa gives back 4 kPa (1e-6)."""
    m = cavity_model()
    assert m.chamber_rest_volume_mm3[0] == pytest.approx(64.0)
    r1 = solve_state(m, Load.pressures([4.0]))
    growth = r1.chamber_volume_mm3[0] - 64.0
    assert growth > 0
    load = Load(np.zeros(1), np.array([growth]), np.array([True]), 1.0, 1.0)
    r2 = solve_state(m, load, options=SolverOptions(tolerance=1e-9))
    assert r2.pressure_kpa[0] == pytest.approx(4.0, rel=1e-6)
    assert r2.chamber_volume_mm3[0] == pytest.approx(64.0 + growth, rel=1e-9)


def test_chamber_winding_is_made_consistent_and_open_surface_refused():
    """A cavity given with every other triangle flipped has its rest volume (64 mm^3, not
    the signed sum) and the same pressure response as the well-wound one; a surface with
    a hole is refused naming the chamber."""
    nodes, tets, cav = structured_box_with_cavity(
        [0, 0, 0], [12, 12, 12], (6, 6, 6), [4, 4, 4], [8, 8, 8]
    )
    mixed = cav.copy()
    mixed[::2] = mixed[::2][:, [0, 2, 1]]
    fixed = np.flatnonzero(nodes[:, 2] == 0.0)
    m = Model.from_arrays(nodes, tets, 100.0, 0.3, fixed_nodes=fixed, chambers={"c": mixed})
    assert m.chamber_rest_volume_mm3[0] == pytest.approx(64.0, rel=1e-12)
    r = solve_state(m, Load.pressures([4.0]))
    r0 = solve_state(cavity_model(), Load.pressures([4.0]))
    assert np.abs(r.x - r0.x).max() < 1e-9 * np.abs(r0.displacement_mm).max() + 1e-12
    with pytest.raises(MeshError, match="chamber c: .*open or non-manifold"):
        Model.from_arrays(nodes, tets, 100.0, 0.3, fixed_nodes=fixed, chambers={"c": cav[1:]})


@pytest.mark.parametrize("E", [1.0, 1e2, 1e4, 1e6])
def test_linear_response_scales_as_one_over_E(E):
    """Small pressure p = 1e-4 E: the volume growth times E / p is the same for E from
    1 kPa to 1 GPa (1e-3)."""
    m = cavity_model(E=E)
    r = solve_state(m, Load.pressures([1e-4 * E]))
    compliance = (r.chamber_volume_mm3[0] - 64.0) * E / (1e-4 * E)
    ref = cavity_model(E=1.0)
    r0 = solve_state(ref, Load.pressures([1e-4]))
    assert compliance == pytest.approx((r0.chamber_volume_mm3[0] - 64.0) / 1e-4, rel=1e-3)


@pytest.mark.parametrize("nu", [0.0, 0.3, 0.45, 0.49, 0.499])
def test_poisson_range_no_nan_and_locking_shows(nu):
    """nu up to 0.499 solves without NaN; near 0.5 the model warns about locking and the
    cantilever gets stiffer than beam theory says (20x2x2 cells: ratio to beam theory
    0.60 at nu = 0.3, 0.55 at nu = 0.499)."""
    tip, m = cantilever_tip((20, 2, 2), nu=nu)
    ratio = tip / beam_theory(nu=nu)
    assert np.isfinite(tip) and 0 < ratio < 1
    if nu >= 0.499:
        assert any("lock" in n for n in m.notes)
        assert ratio < 0.95 * cantilever_tip((20, 2, 2), nu=0.3)[0] / beam_theory(nu=0.3)


def test_pressure_ramp_until_inversion_fails_clearly():
    """A huge pressure on a soft cavity: load stepping converges or a SolverError names
    the state, the residual and the worst element; never NaN."""
    m = cavity_model(E=10.0)
    res = solve_state(m, Load.pressures([2.0]))
    assert np.isfinite(res.x).all() and res.min_det_f > 0
    with pytest.raises(SolverError, match=r"state 7: .*residual .*worst element tet \d+"):
        solve_state(
            m,
            Load.pressures([500.0]),
            label="state 7",
            options=SolverOptions(max_subdivisions=3, max_iterations=15),
        )


@pytest.mark.parametrize("k_n_per_mm", [1e-3, 1.0, 1e6])
def test_jig_stiffness_range(k_n_per_mm):
    """Jig springs from 1e-3 to 1e6 N/mm on a fixed-base block: converges; the stiffest
    holds its nodes on the rotated target (1e-3 mm), the softest barely moves them."""
    nodes, tets = structured_box([0, 0, 0], [30, 10, 10], (6, 2, 2))
    fixed = np.flatnonzero(nodes[:, 0] == 0.0)
    region = nodes_in_box(nodes, [29.9, -1, -1, 31, 11, 11])
    jig = Jig(region, k_n_per_mm * 1000.0, rotate_deg=5.0, axis=(0, 0, 1), pivot_mm=(0.0, 5.0, 5.0))
    m = Model.from_arrays(nodes, tets, 1e4, 0.3, fixed_nodes=fixed, jigs=[jig])
    res = solve_state(m, Load.pressures([]), options=SolverOptions(max_iterations=50))
    gap = np.abs(res.x[region] - jig.targets(nodes)).max()
    move = np.abs(res.displacement_mm[region]).max()
    assert np.isfinite(res.x).all()
    if k_n_per_mm >= 1e6:
        assert gap < 1e-3
    if k_n_per_mm <= 1e-3:
        assert move < 0.05 * np.abs(jig.targets(nodes) - nodes[region]).max()
