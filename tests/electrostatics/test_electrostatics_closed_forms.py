"""The field solver against closed forms: plates, cylinders, sphere over a plane, a line
charge over a dielectric, and the error's rate under refinement (mm, fF)."""

from __future__ import annotations

import numpy as np
import pytest

from fruitcli.electrostatics import assemble, capacitance
from fruitcli.electrostatics import closed_forms as cf
from tests.electrostatics import es_shapes as shapes


def _eps(mesh, values: dict) -> np.ndarray:
    return np.array([values[mesh.regions[r]] for r in mesh.region])


@pytest.mark.parametrize("order", [1, 2])
def test_parallel_plates_with_two_dielectrics(order):
    """Layers 0.5 mm of eps_r 3 and 1 mm of air under a 4 x 4 mm plate: the series
    capacitance 1 / (d1 / (eps0 3 A) + d2 / (eps0 A)), within 1 %, by charge and energy."""
    mesh = shapes.layered_plates(4.0, [0.5, 1.0], 1.0, order)
    k = assemble.stiffness(mesh.nodes, mesh.tets, _eps(mesh, {"layer0": 3.0, "layer1": 1.0}), order)
    exact = 1.0 / (1.0 / cf.parallel_plate(16.0, 0.5, 3.0) + 1.0 / cf.parallel_plate(16.0, 1.0))
    for method in ("charge", "energy"):
        c = capacitance.two_conductor_capacitance(
            k, mesh.surfaces["top"], mesh.surfaces["bottom"], method
        )
        assert c == pytest.approx(exact, rel=0.01)


def test_two_long_parallel_cylinders():
    """a = 0.5 mm, D = 2 mm: C' = pi eps0 / arccosh(2) (fF/mm), within 2 %."""
    length = 0.5
    mesh = shapes.two_cylinders(0.5, 2.0, 10.0, length, 0.1, 2.0, order=2)
    k = assemble.stiffness(mesh.nodes, mesh.tets, 1.0, 2)
    c = capacitance.two_conductor_capacitance(k, mesh.surfaces["left"], mesh.surfaces["right"])
    assert c / length == pytest.approx(cf.two_cylinders_per_length(0.5, 2.0), rel=0.02)


def test_grounded_sphere_over_grounded_plane():
    """R = 1 mm, centre 1.5 mm above the plane: the image series, within 2 %."""
    mesh = shapes.sphere_over_plane(1.0, 1.5, 10.0, 0.15, 3.0, order=2)
    k = assemble.stiffness(mesh.nodes, mesh.tets, 1.0, 2)
    c = capacitance.two_conductor_capacitance(k, mesh.surfaces["sphere"], mesh.surfaces["plane"])
    assert c == pytest.approx(cf.sphere_over_plane(1.0, 1.5), rel=0.02)


def test_sphere_over_plane_series_limits():
    """Far from the plane the series tends to an isolated sphere, 4 pi eps0 R."""
    assert cf.sphere_over_plane(1.0, 1e4) == pytest.approx(
        4 * np.pi * assemble.EPS0_FF_PER_MM, rel=1e-3
    )


def test_line_charge_over_dielectric_half_space():
    """A line charge 1 mm above silicone (eps_r 2.8), air above: with the exact potential
    (the image (e1 - e2) / (e1 + e2) above, the transmitted charge below) held on the
    outer faces and on a 0.05 mm wire around the charge, the wire carries the charge
    within 2 % and the potential matches within 1 % of its range (0.3 mm off the wire); without the
    dielectric the closed form is off by a third of the range."""
    height, length, e_air, e_sil = 1.0, 0.5, 1.0, 2.8
    mesh = shapes.line_charge_slab(height, 0.05, 5.0, length, 0.03, 1.0, order=2)
    k = assemble.stiffness(mesh.nodes, mesh.tets, _eps(mesh, {"upper": e_air, "lower": e_sil}), 2)
    xz = mesh.nodes[:, [0, 2]]
    exact = cf.line_charge_over_dielectric(xz, height, e_air, e_sil, charge_fc_per_mm=1.0)
    fixed = np.concatenate([mesh.surfaces["wire"], mesh.surfaces["outer"]])
    u = capacitance.solve_potential(k, fixed, exact[fixed])
    charge = capacitance.conductor_charge(k, u, mesh.surfaces["wire"])
    assert charge / length == pytest.approx(1.0, rel=0.02)
    away = np.hypot(xz[:, 0], xz[:, 1] - height) > 0.3  # off the wire's log singularity
    span = np.ptp(exact[away])
    assert np.abs(u - exact)[away].max() < 0.01 * span
    no_dielectric = cf.line_charge_over_dielectric(xz, height, e_air, e_air)
    assert np.abs(no_dielectric - exact)[away].max() > 0.3 * span
    assert cf.image_factor(e_air, e_sil) == pytest.approx(-1.8 / 3.8)


def _slope(n_nodes, errors) -> float:
    """Log-log slope of the error against h = n^(-1/3)."""
    h = np.asarray(n_nodes, float) ** (-1.0 / 3.0)
    return float(np.polyfit(np.log(h), np.log(errors), 1)[0])


@pytest.mark.parametrize(
    "order, sizes, rate", [(1, (0.2, 0.14, 0.1), 2.0), (2, (0.3, 0.2, 0.14), 3.0)]
)
def test_potential_error_falls_at_the_element_rate(order, sizes, rate):
    """u = exp(x) cos(y) on a box, Dirichlet on x = 0, 1: the nodal RMS error falls as
    h^(p+1) (2 for linear, 3 for quadratic tets), within 0.5."""
    n, err = [], []
    for h in sizes:
        mesh = shapes.harmonic_box(h, order)
        k = assemble.stiffness(mesh.nodes, mesh.tets, 1.0, order)
        exact = np.exp(mesh.nodes[:, 0]) * np.cos(mesh.nodes[:, 1])
        fixed = np.concatenate([mesh.surfaces["x0"], mesh.surfaces["x1"]])
        u = capacitance.solve_potential(k, fixed, exact[fixed])
        n.append(len(mesh.nodes))
        err.append(np.sqrt(np.mean((u - exact) ** 2)))
    assert err[-1] < err[0]
    assert abs(_slope(n, err) - rate) < 0.5


def test_capacitance_error_falls_at_the_element_rate():
    """Concentric spheres (1 and 2 mm), linear tets: the capacitance (an energy) error
    falls as h^2, within 0.5."""
    n, err = [], []
    for h in (0.3, 0.2, 0.15):
        mesh = shapes.concentric_spheres(1.0, 2.0, h, 1)
        k = assemble.stiffness(mesh.nodes, mesh.tets, 1.0, 1)
        c = capacitance.two_conductor_capacitance(k, mesh.surfaces["inner"], mesh.surfaces["outer"])
        n.append(len(mesh.nodes))
        err.append(abs(c / cf.concentric_spheres(1.0, 2.0) - 1.0))
    assert err[-1] < 0.01
    assert abs(_slope(n, err) - 2.0) < 0.5


def test_mutual_capacitance_is_symmetric():
    """C_12 measured from either side is the same (the stiffness is symmetric)."""
    mesh = shapes.two_cylinders(0.5, 2.0, 4.0, 0.5, 0.2, 1.0, order=1)
    k = assemble.stiffness(mesh.nodes, mesh.tets, 1.0, 1)
    left, right = mesh.surfaces["left"], mesh.surfaces["right"]
    assert capacitance.mutual_capacitance(k, left, right) == pytest.approx(
        capacitance.mutual_capacitance(k, right, left), rel=1e-9
    )


def test_quadratic_element_stiffness_annihilates_constants():
    """Each row of a quadratic element's matrix sums to 0 (a constant has no field) and
    its trace is positive."""
    from fruitcli.fem.elements.lagrange import TET10_EDGES

    corners = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    mid = 0.5 * (corners[TET10_EDGES[:, 0]] + corners[TET10_EDGES[:, 1]])
    ke = assemble.element_stiffness(np.vstack([corners, mid]), np.arange(10)[None], 2)[0]
    assert np.allclose(ke.sum(axis=1), 0.0, atol=1e-12)
    assert np.allclose(ke, ke.T)
    assert np.trace(ke) > 0
