"""Observed orders of convergence of the p1 and p2 elements as the mesh is refined, as
scikit-fem's tests check theirs: Lamé's thick sphere under internal pressure (nodal
displacements against the closed form) and the cantilever under its weight (tip
deflection, from the differences between successive meshes), on structured meshes
(no gmsh). p1 is the paper's corotational element on linear tets (`Model`), p2 the
quadratic tet with mean dilatation (`ContinuumModel`, neo-Hookean); both are linear
elastic at the small loads used here."""

import itertools

import numpy as np
import pytest
from scipy.optimize import brentq

from fruitcli.fem.continuum import ContinuumModel
from fruitcli.fem.corotational_model import Model
from fruitcli.fem.elements.quadratic import curve_onto_ellipsoid, quadratic_mesh
from fruitcli.fem.materials.build import material
from fruitcli.fem.meshing.grid import shell_octant, structured_box
from fruitcli.fem.meshing.topology import boundary_faces
from fruitcli.fem.solver.options import SolverOptions
from fruitcli.fem.solver.state import solve_state
from fruitcli.fem.state_load import Load
from fruitcli.fem.units import body_force_mn_mm3

ACCURATE = SolverOptions(tolerance=1e-10, linear_solver="direct")


def observed_order(sizes, values) -> float:
    """Order q of f_h = f + C h^q through three results on meshes of sizes h1 > h2 > h3:
    the root of (h1^q - h2^q) / (h2^q - h3^q) = (f1 - f2) / (f2 - f3)
    (log((f1 - f2) / (f2 - f3)) / log(r) when h1 / h2 = h2 / h3 = r)."""
    h1, h2, h3 = sizes
    ratio = (values[0] - values[1]) / (values[1] - values[2])

    def mismatch(q):
        return (h1**q - h2**q) / (h2**q - h3**q) - ratio

    assert mismatch(0.05) < 0 < mismatch(12.0), f"no order in (0.05, 12) fits {values}"
    return brentq(mismatch, 0.05, 12.0)


def error_orders(sizes, errors) -> list[float]:
    """log(e1 / e2) / log(h1 / h2) for each pair of successive meshes."""
    return [
        float(np.log(errors[i] / errors[i + 1]) / np.log(sizes[i] / sizes[i + 1]))
        for i in range(len(errors) - 1)
    ]


# -- Lamé's thick sphere ----------------------------------------------------------------

A, B = 10.0, 20.0  # mm, inner and outer radius
E, NU = 100.0, 0.3  # kPa
P = 1e-6  # kPa: p / E = 1e-8, so the geometric nonlinearity is far below every error


def lame_displacement(x: np.ndarray) -> np.ndarray:
    """Closed form u(x) (n, 3) mm under P: u_r = p a^3 / (E (b^3 - a^3)) ((1 - 2 nu) r
    + (1 + nu) b^3 / (2 r^2)), radial."""
    r = np.linalg.norm(x, axis=1)
    u_r = P * A**3 / (E * (B**3 - A**3)) * ((1 - 2 * NU) * r + (1 + NU) * B**3 / (2 * r**2))
    return x * (u_r / r)[:, None]


def symmetry_rollers(nodes: np.ndarray) -> list:
    """Each node on a plane x_d = 0 held in u_d (the closed form's symmetry)."""
    return [
        (np.flatnonzero(np.abs(nodes[:, d]) < 1e-9), np.zeros(3), np.eye(3)[d] > 0)
        for d in range(3)
    ]


def nodal_error(nodes: np.ndarray, displacement: np.ndarray) -> float:
    """RMS over the nodes of |u_h - u|, relative to u_r(a)."""
    err = np.linalg.norm(displacement - lame_displacement(nodes), axis=1)
    u_a = lame_displacement(np.array([[A, 0.0, 0.0]]))[0, 0]
    return float(np.sqrt(np.mean(err**2)) / u_a)


def whole_shell(n: int):
    """The shell a <= r <= b as the eight mirror images of `shell_octant(a, b, n, n)`,
    coincident nodes merged: nodes, tets and the closed inner wall (the corotational
    model's chamber must be a closed surface)."""
    nodes, tets, wall = shell_octant(A, B, n, n)
    xs, ts, ws = [], [], []
    for k, sign in enumerate(itertools.product((1.0, -1.0), repeat=3)):
        odd = np.prod(sign) < 0  # a reflection turns the elements inside out
        xs.append(nodes * sign)
        ts.append(k * len(nodes) + (tets[:, [0, 2, 1, 3]] if odd else tets))
        ws.append(k * len(nodes) + (wall[:, [0, 2, 1]] if odd else wall))
    x = np.vstack(xs)
    _, first, merged = np.unique(np.round(x, 9), axis=0, return_index=True, return_inverse=True)
    merged = merged.ravel()
    return x[first], merged[np.vstack(ts)], merged[np.vstack(ws)]


def lame_error_p1(n: int) -> float:
    nodes, tets, wall = whole_shell(n)
    m = Model.from_arrays(
        nodes, tets, E, NU, chambers={"c": wall}, prescribed=symmetry_rollers(nodes)
    )
    res = solve_state(m, Load.pressures([P]), options=SolverOptions(tolerance=1e-10))
    return nodal_error(nodes, res.displacement_mm)


def lame_error_p2(n: int, curved: bool) -> float:
    """The octant on rollers; the walls' edge nodes moved onto their spheres when
    `curved`, else left at the chords' midpoints (a faceted shell)."""
    nodes, tets, wall = shell_octant(A, B, n, n)
    faces = boundary_faces(nodes, tets)
    outer = faces[np.all(np.isclose(np.linalg.norm(nodes[faces], axis=2), B), axis=1)]
    nodes, tets, (wall, outer) = quadratic_mesh(nodes, tets, [wall, outer])
    if curved:
        for tris, radius in ((wall, A), (outer, B)):
            assert (
                curve_onto_ellipsoid(nodes, tets, np.unique(tris[:, 3:]), [0, 0, 0], [radius] * 3)
                == 0
            )
    m = ContinuumModel.from_arrays(
        nodes,
        tets,
        material("neo-hookean", E, NU),
        "p2",
        chambers={"c": wall},
        prescribed=symmetry_rollers(nodes),
    )
    res = solve_state(m, Load.pressures([P]), options=ACCURATE)
    return nodal_error(nodes, res.displacement_mm)


def test_lame_sphere_p1_converges_at_second_order():
    """Corotational linear tets on the whole shell (8 mirrored octants, n = 2, 4, 6 cells
    per patch edge and layers, up to 6062 nodes): the nodal displacement error falls as
    h^2 (linear elements' L2 order) and the faceted walls, chords O(h^2) off their
    spheres, cost the same order. Asserted: every pair's order within [1.7, 2.5]
    (measured 1.84, 1.98)."""
    sizes = [1 / 2, 1 / 4, 1 / 6]
    errors = [lame_error_p1(n) for n in (2, 4, 6)]
    orders = error_orders(sizes, errors)
    assert errors[-1] < 0.02
    assert all(1.7 <= q <= 2.5 for q in orders), orders


@pytest.mark.slow
@pytest.mark.parametrize(("curved", "expected"), [(True, 3.0), (False, 2.0)])
def test_lame_sphere_p2_order_is_three_curved_two_faceted(curved, expected):
    """Quadratic tets with mean dilatation on the octant (n = 2, 4, 8, up to 13889
    nodes). With both walls curved onto their spheres (geometry error O(h^3)) the nodal
    displacement error falls as h^3, the quadratic element's L2 order. Mean dilatation
    (a pressure constant per element) would in general cap it at h^2, but Lamé's mean
    stress is uniform (sigma_rr + 2 sigma_tt: the r^-3 terms cancel), so the constant
    pressure is exact and the full order shows. Left faceted, the walls are O(h^2) off
    and cap it at 2. Asserted: every pair's order within [expected - 0.3, expected +
    0.5] (measured 2.87, 3.01 curved; 2.10, 2.04 faceted)."""
    sizes = [1 / 2, 1 / 4, 1 / 8]
    errors = [lame_error_p2(n, curved) for n in (2, 4, 8)]
    orders = error_orders(sizes, errors)
    assert all(expected - 0.3 <= q <= expected + 0.5 for q in orders), orders


# -- the cantilever under its weight ------------------------------------------------------

L, W, H = 100.0, 10.0, 10.0  # mm
RHO, GRAVITY = 1000.0, [0.0, 0.0, -9.81]
BEAM_E = 1e5  # kPa


def beam_theory() -> float:
    """Tip deflection (mm): Euler-Bernoulli q L^4 / 8EI plus Timoshenko's shear
    q L^2 / (2 kappa G A), q the weight per length (mN/mm)."""
    q = -body_force_mn_mm3(RHO, GRAVITY)[2] * W * H
    kappa = 10 * (1 + NU) / (12 + 11 * NU)
    shear_modulus = BEAM_E / (2 * (1 + NU))
    return q * L**4 / (8 * BEAM_E * W * H**3 / 12) + q * L**2 / (2 * kappa * shear_modulus * W * H)


def tip_deflection(element: str, n: int) -> float:
    """Mean downward displacement (mm) of the free end x = L, integrated over its face,
    of the beam clamped at x = 0 on (10 n, n, n) cells (h = H / n)."""
    nodes, tets = structured_box([0, 0, 0], [L, W, H], (10 * n, n, n))
    faces = boundary_faces(nodes, tets)
    end = faces[np.all(nodes[faces][:, :, 0] == L, axis=1)]
    corners = nodes[end]
    area = 0.5 * np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    if element == "p1":
        m = Model.from_arrays(
            nodes,
            tets,
            BEAM_E,
            NU,
            density_kg_m3=RHO,
            gravity_m_s2=GRAVITY,
            fixed_nodes=np.flatnonzero(nodes[:, 0] == 0.0),
        )
        u = solve_state(m, Load.pressures([])).displacement_mm
        face_mean = u[end, 2].mean(axis=1)  # exact for a linear triangle
    else:
        nodes, tets, (end,) = quadratic_mesh(nodes, tets, [end])
        m = ContinuumModel.from_arrays(
            nodes,
            tets,
            material("neo-hookean", BEAM_E, NU),
            "p2",
            density_kg_m3=RHO,
            gravity_m_s2=GRAVITY,
            fixed_nodes=np.flatnonzero(nodes[:, 0] == 0.0),
        )
        u = solve_state(m, Load.pressures([]), options=ACCURATE).displacement_mm
        face_mean = u[end[:, 3:], 2].mean(axis=1)  # a quadratic's mean: its edge nodes'
    return -float((area * face_mean).sum() / (W * H))


@pytest.mark.slow
def test_cantilever_tip_orders():
    """Tip deflection against cell size (successive differences, no reference needed;
    beam theory is itself only good to about a percent). A smooth solution would give
    the tip deflection, a functional, at order 2p (2 for p1, 4 for p2); but where the
    clamp meets the free faces the stress is singular (r^(lambda - 1), lambda about 0.7
    for a clamped-free right angle in plane strain at nu = 0.3), which on uniform
    meshes eventually limits any element to about 2 lambda = 1.4.
    p1 (4, 6, 8 cells through the thickness): linear tets are too stiff in bending by a
    parasitic shear ~ (h / H)^2 that is not yet small, so the order climbs toward 2
    from below (measured 1.27 on 2, 4, 8 cells; 1.63 on 4, 6, 8; 1.75 on 6, 8, 12).
    Asserted: within [1.3, 2.1], and the extrapolated deflection within 2 % of
    Euler-Bernoulli plus Timoshenko's shear (`beam_theory`, 0.1487 mm; measured
    -0.15 %).
    p2 (2, 3, 4 cells): no parasitic shear; measured 2.23 (2.3 on 3, 4, 6 and 2.25 on
    2, 4, 8 cells), below the smooth 4: the singularity's share already shows.
    Asserted: within [1.7, 3.0] and the extrapolation within 1.5 % of beam theory
    (measured -0.8 %; the order still falling, the extrapolation undershoots: 8 cells
    give 0.1478 mm)."""
    theory = beam_theory()
    for element, cells, band, rel in (
        ("p1", (4, 6, 8), (1.3, 2.1), 0.02),
        ("p2", (2, 3, 4), (1.7, 3.0), 0.015),
    ):
        sizes = [H / n for n in cells]
        tips = [tip_deflection(element, n) for n in cells]
        q = observed_order(sizes, tips)
        limit = tips[2] + (tips[2] - tips[1]) / ((sizes[1] / sizes[2]) ** q - 1)
        print(f"{element}: tips {tips}, order {q:.2f}, extrapolated {limit:.5f} mm")
        assert band[0] <= q <= band[1], (element, q)
        assert limit == pytest.approx(theory, rel=rel), (element, limit)
