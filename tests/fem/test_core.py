"""Closed-form checks of the corotational tet model (no gmsh): element stiffness,
rigid-motion invariance, objectivity, energy gradient, tangent, patch test."""

import numpy as np
import pytest

from fruitcli.errors import MeshError, SolverError
from fruitcli.fem.corotational_model import Model
from fruitcli.fem.elements import tet4
from fruitcli.fem.loads.springs import rotation_matrix
from fruitcli.fem.materials import corotation
from fruitcli.fem.meshing.grid import structured_box
from fruitcli.fem.solver.linsolve import TangentSolver
from fruitcli.fem.solver.options import SolverOptions
from fruitcli.fem.solver.state import solve_state
from fruitcli.fem.state_load import Load

RNG = np.random.default_rng(7)


def bar(cells=(6, 2, 2), size=(30.0, 10.0, 10.0)):
    return structured_box([0, 0, 0], size, cells)


def test_element_stiffness_has_six_zero_modes():
    """K0 of one tet: rank 6, symmetric, positive semi-definite."""
    nodes = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.3, 1.0]]) * 3.0
    tets = np.array([[0, 1, 2, 3]])
    lam, mu = tet4.lame_parameters(100.0, 0.3)
    k = tet4.element_stiffness(
        tet4.shape_gradients(nodes, tets), tet4.signed_volumes(nodes, tets), lam, mu
    )[0]
    ev = np.linalg.eigvalsh(k)
    assert np.allclose(k, k.T, atol=1e-12)
    assert np.sum(np.abs(ev) < 1e-10 * ev.max()) == 6
    assert ev.min() > -1e-10 * ev.max()


@pytest.mark.parametrize("angle", [30.0, 170.0])
def test_rigid_motion_gives_zero_force(angle):
    """x = Q X + t: zero internal force (to 1e-12 relative of a 1% strain force)."""
    nodes, tets = bar()
    m = Model.from_arrays(nodes, tets, 100.0, 0.3, fixed_nodes=[0])
    q = rotation_matrix([1.0, 2.0, 0.5], angle)
    x = nodes @ q.T + np.array([5.0, -3.0, 2.0])
    f = m.internal_forces(x, m.rotations(x)[0])
    stretch = nodes * np.array([1.01, 1.0, 1.0])
    scale = np.abs(m.internal_forces(stretch, m.rotations(stretch)[0])).max()
    assert np.abs(f).max() < 1e-12 * scale * 1e2


def test_objectivity():
    """f(Q x) = Q f(x) for a deformed configuration."""
    nodes, tets = bar()
    m = Model.from_arrays(nodes, tets, 100.0, 0.3, fixed_nodes=[0])
    x = nodes + 0.3 * RNG.normal(size=nodes.shape)
    q = rotation_matrix([0.3, -1.0, 0.2], 75.0)
    f = m.internal_forces(x, m.rotations(x)[0])
    fq = m.internal_forces(x @ q.T, m.rotations(x @ q.T)[0])
    assert np.allclose(fq, f @ q.T, atol=1e-9 * np.abs(f).max())


def test_forces_are_energy_gradient_and_tangent_is_close():
    """Central differences of the strain energy equal the forces (1e-6 rel.); the
    warped tangent matches the force derivative up to the neglected dR/dx term."""
    nodes, tets = bar((3, 1, 1), (9.0, 3.0, 3.0))
    m = Model.from_arrays(nodes, tets, 100.0, 0.3, fixed_nodes=np.flatnonzero(nodes[:, 0] == 0))
    x = nodes + 0.05 * RNG.normal(size=nodes.shape)
    f, _ = corotation.forces_and_energy(x, m.rest, m.tets, m.k0, m.rotations(x)[0])
    v = RNG.normal(size=nodes.shape)
    eps = 1e-6

    def energy(y):
        return corotation.forces_and_energy(y, m.rest, m.tets, m.k0, m.rotations(y)[0])[1]

    dfd = (energy(x + eps * v) - energy(x - eps * v)) / (2 * eps)
    assert dfd == pytest.approx(float(np.sum(f * v)), rel=1e-6)
    # tangent against the force derivative at 1 % strain: within a few per cent
    y = nodes * np.array([1.01, 1.0, 1.0])
    s = TangentSolver(m, "direct")
    rot = m.rotations(y)[0]
    s.update(rot)
    w = np.zeros(3 * len(nodes))
    w[m.pattern.free] = RNG.normal(size=len(m.pattern.free))
    kv = s.matvec(w[m.pattern.free])
    f0 = m.internal_forces(y, rot).reshape(-1)
    y1 = y + 1e-7 * w.reshape(-1, 3)
    f1 = m.internal_forces(y1, m.rotations(y1)[0]).reshape(-1)
    fd = ((f1 - f0) / 1e-7)[m.pattern.free]
    assert np.linalg.norm(fd - kv) < 0.05 * np.linalg.norm(fd)


def test_patch_test_affine_field_reproduced_inside():
    """Boundary nodes moved by u = A X + c (5 % strain, rotation): interior nodes land
    on the same affine field to 1e-7 mm."""
    nodes, tets = structured_box([0, 0, 0], [10, 8, 6], (4, 4, 3))
    lo, hi = nodes.min(0), nodes.max(0)
    boundary = np.flatnonzero(np.any(np.isclose(nodes, lo) | np.isclose(nodes, hi), axis=1))
    a = np.array([[0.05, 0.02, -0.01], [0.01, -0.03, 0.02], [0.0, 0.04, 0.02]])
    a = rotation_matrix([0, 0, 1], 20.0) @ (np.eye(3) + a) - np.eye(3)
    exact = nodes + nodes @ a.T + np.array([1.0, 2.0, -0.5])
    m = Model.from_arrays(nodes, tets, 100.0, 0.35, fixed_nodes=boundary)
    start = nodes.copy()
    start[boundary] = exact[boundary]
    res = solve_state(
        m,
        Load.pressures([], gravity=0.0, jig=0.0),
        x_start=start,
        load_start=Load.zero(0),
        options=SolverOptions(tolerance=1e-10),
    )
    assert np.abs(res.x - exact).max() < 1e-7


def test_zero_load_returns_rest_exactly():
    nodes, tets = bar()
    m = Model.from_arrays(
        nodes,
        tets,
        100.0,
        0.3,
        fixed_nodes=[0, 1, 2],
        density_kg_m3=1000.0,
        gravity_m_s2=[0, 0, -9.81],
    )
    res = solve_state(m, Load.pressures([], gravity=0.0))
    assert res.iterations == 0
    assert np.array_equal(res.x, nodes)


def test_sliver_tet_is_refused_before_solving():
    nodes, tets = bar((2, 1, 1), (6.0, 3.0, 3.0))
    nodes = nodes.copy()
    # flatten one tet: move a node onto the plane of the opposite face
    t = tets[0]
    p = nodes[t]
    n = np.cross(p[2] - p[1], p[3] - p[1])
    n /= np.linalg.norm(n)
    nodes[t[0]] -= (1 - 1e-6) * np.dot(p[0] - p[1], n) * n
    with pytest.raises(MeshError, match="sliver"):
        Model.from_arrays(nodes, tets, 100.0, 0.3, fixed_nodes=[1])


def test_bad_material_is_refused():
    nodes, tets = bar()
    with pytest.raises(SolverError, match="young_modulus_kpa"):
        Model.from_arrays(nodes, tets, 0.0, 0.3)
    with pytest.raises(SolverError, match="poisson_ratio"):
        Model.from_arrays(nodes, tets, 100.0, 0.5)


def test_barycentric_inside_outside_and_affine_motion():
    """Points inside get weights in [0, 1] summing to 1; a point 0.1 mm outside maps to
    a boundary tet with a small negative weight; an affine motion moves mapped points
    affinely (1e-12)."""
    from fruitcli.fem.elements import barycentric

    nodes, tets = structured_box([0, 0, 0], [10, 10, 10], (3, 3, 3))
    pts = np.array([[1.0, 2.0, 3.0], [9.9, 0.1, 5.0], [5.0, 5.0, 10.1]])
    tet, w, outside = barycentric.locate(nodes, tets, pts)
    assert np.allclose(w.sum(axis=1), 1.0)
    assert (w[:2] >= -1e-12).all() and outside[:2].max() == 0.0
    assert 0 < outside[2] < 0.2
    assert np.allclose(barycentric.apply(nodes, tets, tet, w), pts, atol=1e-12)
    a = np.array([[1.1, 0.2, 0.0], [0.0, 0.9, 0.1], [0.1, 0.0, 1.0]])
    moved = barycentric.apply(np.stack([nodes @ a.T + 1.0]), tets, tet, w)
    assert np.allclose(moved[0], pts @ a.T + 1.0, atol=1e-12)


def test_consistent_tangent_matches_force_derivative_and_projection_is_psd():
    """The consistent element tangent equals the central-difference derivative of the
    corotational forces (1e-6 rel.) at 30 % random strain; its projection has no
    negative eigenvalue (1e-9 of the largest)."""
    nodes, tets = bar((3, 1, 1), (9.0, 3.0, 3.0))
    m = Model.from_arrays(nodes, tets, 100.0, 0.3, fixed_nodes=[0])
    x = nodes + 0.3 * RNG.normal(size=nodes.shape)
    f, rot, _ = m.kinematics(x)
    k = m.tangent_blocks(rot, f, project=False)
    kp = m.tangent_blocks(rot, f, project=True)
    e = 2
    v = RNG.normal(size=(4, 3))

    def force(y):
        xx = x.copy()
        xx[m.tets[e]] = y
        r = m.rotations(xx)[0]
        return corotation.forces_and_energy(
            xx, m.rest, m.tets[e : e + 1], m.k0[e : e + 1], r[e : e + 1]
        )[0][m.tets[e]]

    eps = 1e-6
    fd = (force(x[m.tets[e]] + eps * v) - force(x[m.tets[e]] - eps * v)).ravel() / (2 * eps)
    assert np.linalg.norm(k[e] @ v.ravel() - fd) < 1e-6 * np.linalg.norm(fd)
    ev = np.linalg.eigvalsh(kp)
    assert ev.min() > -1e-9 * ev.max()


def test_soft_cantilever_converges_quadratically():
    """A 40 x 8 x 8 mm cantilever of E = 10 kPa sagging under gravity (tip about 26 mm,
    which stalled with the warped tangent) converges to 1e-10; a further 10 % gravity
    step from that state needs at most 4 Newton iterations with the fresh tangent."""
    nodes, tets = structured_box([0, 0, 0], [40.0, 8.0, 8.0], (10, 2, 2))
    m = Model.from_arrays(
        nodes,
        tets,
        10.0,
        0.3,
        density_kg_m3=1070.0,
        gravity_m_s2=[0, 0, -9.81],
        fixed_nodes=np.flatnonzero(nodes[:, 0] == 0),
    )
    opts = SolverOptions(tolerance=1e-10, linear_solver="direct")
    first = solve_state(m, Load.pressures([], gravity=1.0, jig=0.0), options=opts)
    assert nodes[:, 2].min() - first.x[:, 2].min() > 15.0
    res = solve_state(
        m,
        Load.pressures([], gravity=1.1, jig=0.0),
        x_start=first.x,
        load_start=Load.pressures([], gravity=1.0, jig=0.0),
        options=opts,
    )
    assert res.iterations <= 4 and res.residual <= 1e-10 and res.subdivisions == 0


@pytest.mark.parametrize("project", [False, True])
def test_compiled_kernels_match_per_element_ones(project):
    """The compiled kernels the solver uses (F, forces, energy, tangent product) agree
    with the per-element reference ones (Ds Dm^-1, R K0 (R^T x - X), assembled
    consistent tangent blocks) to 1e-12 relative, at 30 % random strain with some
    elements inverted. The warm-started rotations equal the cold polar decomposition,
    also where the warm start is 179 degrees off and the element falls back to it."""
    from fruitcli.fem.materials import corotation_kernels as kernels

    nodes, tets = bar((4, 2, 2), (12.0, 6.0, 6.0))
    m = Model.from_arrays(nodes, tets, 100.0, 0.3, fixed_nodes=[0])
    x = nodes + 0.3 * RNG.normal(size=nodes.shape)
    x[m.tets[0, 0]] = 2 * x[m.tets[0]].mean(axis=0) - x[m.tets[0, 0]]  # invert tet 0
    m.kinematics(x + 0.05 * RNG.normal(size=nodes.shape))  # a nearby warm start
    far = np.array([[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]])
    c, s = np.cos(np.radians(1.0)), np.sin(np.radians(1.0))
    far = far @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # 179 deg about z
    m.__dict__["_rot_guess"][5:9] = far
    guess = m.__dict__["_rot_guess"].copy()
    f, rot, det = m.kinematics(x)
    assert det.min() < 0
    cold = kernels.kinematics(
        x,
        m.tets,
        m.grads,
        guess,
        True,
        corotation.POLAR_WARM_ITERATIONS,
        corotation.POLAR_WARM_STOP,
    )[3]
    assert cold[5:9].all() and cold[det <= 0].all() and not cold.all()
    f_ref = corotation.deformation_gradients(x, m.tets, m.dm_inv)
    assert np.allclose(f, f_ref, rtol=0, atol=1e-12 * np.abs(f_ref).max())
    assert np.allclose(det, corotation.det3(f_ref), rtol=1e-12, atol=1e-14)
    assert np.abs(rot - corotation.polar_rotations(f_ref)).max() < 1e-12
    force, energy = m.forces_and_energy(f, rot)
    force_ref, energy_ref = corotation.forces_and_energy(x, m.rest, m.tets, m.k0, rot)
    assert np.abs(force - force_ref).max() < 1e-12 * np.abs(force_ref).max()
    assert abs(energy - energy_ref) < 1e-12 * energy_ref
    lam, mu = m.lame_kpa
    t = corotation.skew_stiffness(f, rot, lam, mu, project)
    v = RNG.normal(size=nodes.shape)
    for t_world, blocks in (
        (t, m.tangent_blocks(rot, f, project)),
        (None, m.tangent_blocks(rot, None)),
    ):
        kv = m.apply_tangent(rot, t_world, v)
        kv_ref = corotation.scatter_nodes(
            m.tets, (blocks @ v[m.tets].reshape(-1, 12, 1)).reshape(-1, 4, 3), len(nodes)
        )
        assert np.abs(kv - kv_ref).max() < 1e-12 * np.abs(kv_ref).max()


@pytest.mark.parametrize("project", [False, True])
def test_rotation_term_closed_form_matches_eigendecomposition(project):
    """T' = R (2 mu I + 2 c (tr S I - S)^-1) R^T from the compiled closed form (where it
    is safe) and eigh (elsewhere) equals the eigendecomposition formula on every element,
    at 30 % random strain (some elements compressed, so the clamp acts)."""
    nodes, tets = bar((4, 2, 2), (12.0, 6.0, 6.0))
    m = Model.from_arrays(nodes, tets, 100.0, 0.3, fixed_nodes=[0])
    x = nodes + 0.3 * RNG.normal(size=nodes.shape)
    f, rot, det = m.kinematics(x)
    ok = det > 0.05
    f, rot = f[ok], rot[ok]
    lam, mu = m.lame_kpa
    t = corotation.skew_stiffness(f, rot, lam, mu, project)
    s = np.transpose(rot, (0, 2, 1)) @ f
    sig, u = np.linalg.eigh(0.5 * (s + np.transpose(s, (0, 2, 1))))
    tr = sig.sum(axis=1, keepdims=True)
    th = 2 * mu + 2 * (lam * (tr - 3) - 2 * mu) / (tr - sig)
    if project:
        assert (th < 0).any()  # the clamp is exercised
        th = np.maximum(th, 0.0)
    ru = rot @ u
    ref = (ru * th[:, None, :]) @ np.transpose(ru, (0, 2, 1))
    assert np.abs(t - ref).max() < 1e-9 * np.abs(ref).max()


def test_follower_pressure_stiffness_matches_the_pressure_force_derivative():
    """The load stiffness -p d^2V/dx^2 (the tangent's follower-pressure part) equals the
    central-difference derivative of -p H(x) (1e-7 rel.) on a randomly deformed cavity."""
    from fruitcli.fem.meshing.grid import structured_box_with_cavity

    nodes, tets, cav = structured_box_with_cavity(
        [0, 0, 0], [12, 12, 12], (4, 4, 4), [3, 3, 3], [9, 9, 9]
    )
    m = Model.from_arrays(
        nodes, tets, 100.0, 0.3, chambers={"c": cav}, fixed_nodes=np.flatnonzero(nodes[:, 2] == 0.0)
    )
    x = nodes + 0.4 * RNG.normal(size=nodes.shape)
    p = np.array([7.0])
    k = m.load_stiffness(x, p)
    v = RNG.normal(size=nodes.shape)
    load = Load.pressures(p, gravity=0.0, jig=0.0)

    def force(y):
        return m.external_forces(y, p, load).reshape(-1)[m.pattern.free]

    eps = 1e-6
    fd = -(force(x + eps * v) - force(x - eps * v)) / (2 * eps)
    kv = k @ v.reshape(-1)[m.pattern.free]
    assert np.linalg.norm(kv - fd) < 1e-7 * np.linalg.norm(fd)
