"""fruit's own winding number against closed forms: one triangle, a square, a closed
sphere; the Barnes-Hut tree against the exact sum; the crossing count on a closed
surface's grid against the tree, including lines that run exactly through a vertex."""

import numpy as np
import pytest
import trimesh

from fruitcli.geometry.mesh import winding
from fruitcli.geometry.mesh.columns import RAY_JITTER_MM
from fruitcli.geometry.mesh.solid_angle import SolidAngleTree, exact_winding
from tests.helpers.artist_meshes import overlapping_figure, sphere_with_holes, teapot_with_open_lid

TREE_TOLERANCE = 0.01
"""The tree at beta = 2 stays within this of the exact sum (measured: at most 0.0077
on the meshes below at random points, 0.008 near the default Fruit's surface)."""


def _square(n: int):
    """The square [-1, 1]^2 at z = 0 as 2 n^2 triangles facing +z."""
    g = np.linspace(-1.0, 1.0, n + 1)
    x, y = np.meshgrid(g, g, indexing="ij")
    v = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    i = np.arange(len(v)).reshape(n + 1, n + 1)
    a, b, c, d = i[:-1, :-1].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel(), i[:-1, 1:].ravel()
    return v, np.r_[np.c_[a, b, c], np.c_[a, c, d]]


def _square_closed_form(p: np.ndarray) -> np.ndarray:
    """Winding number of the +z-facing square [-1, 1]^2 at points p (k, 3), z != 0: minus
    its solid angle over 4 pi (a point above sees the front: it is outside), the solid
    angle from the corner formula atan(x y / (z sqrt(x^2 + y^2 + z^2)))."""
    x, y, z = p.T

    def corner(cx, cy):
        dx, dy = cx - x, cy - y
        return np.arctan(dx * dy / (z * np.sqrt(dx**2 + dy**2 + z**2)))

    omega = corner(1, 1) - corner(-1, 1) - corner(1, -1) + corner(-1, -1)
    return -omega / (4 * np.pi)


def test_one_triangle_subtends_an_octant():
    """The triangle (e1, e2, e3) seen from the origin covers one octant of the sphere
    of directions: w = 1/8, negative from the far side's mirror point."""
    v = np.eye(3)
    f = np.array([[0, 1, 2]])
    w = exact_winding(v, f, np.array([[0.0, 0, 0], [2.0 / 3, 2.0 / 3, 2.0 / 3]]))
    assert w[0] == pytest.approx(1 / 8, abs=1e-14)
    assert w[1] == pytest.approx(-1 / 8, abs=1e-14)


def test_square_exact_and_tree_match_the_closed_form():
    v, f = _square(60)
    rng = np.random.default_rng(3)
    z = rng.uniform(0.05, 3.0, 3000) * rng.choice([-1.0, 1.0], 3000)
    p = np.c_[rng.uniform(-2, 2, 3000), rng.uniform(-2, 2, 3000), z]
    want = _square_closed_form(p)
    assert want[np.abs(p[:, :2]).max(axis=1) < 1].max() > 0.4  # near the square: +-1/2
    assert np.abs(exact_winding(v, f, p) - want).max() < 1e-10
    assert np.abs(SolidAngleTree(v, f)(p) - want).max() < TREE_TOLERANCE
    # on the axis at height 1: 4 arcsin(1/2) / (4 pi) = 1/6
    assert exact_winding(v, f, np.array([[0, 0, -1.0]]))[0] == pytest.approx(1 / 6, abs=1e-14)


def test_closed_sphere_is_one_inside_and_zero_outside():
    s = trimesh.creation.icosphere(4, 10.0)
    rng = np.random.default_rng(1)
    d = rng.normal(size=(3000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    r = rng.uniform(0.0, 30.0, 3000)
    r = r[np.abs(r - 10.0) > 0.5]  # the facets lie between 9.9 and 10 mm
    p = d[: len(r)] * r[:, None]
    want = (r < 10.0).astype(float)
    assert np.abs(exact_winding(s.vertices, s.faces, p) - want).max() < 1e-6
    tree = SolidAngleTree(s.vertices, s.faces)
    assert np.abs(tree(p) - want).max() < TREE_TOLERANCE
    assert winding.Winding(s.vertices, s.faces).closed


@pytest.mark.parametrize("make", [sphere_with_holes, overlapping_figure, teapot_with_open_lid])
def test_tree_agrees_with_the_exact_sum(make):
    m = make()
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    rng = np.random.default_rng(7)
    lo, hi = v.min(axis=0) - 5, v.max(axis=0) + 5
    p = lo + (hi - lo) * rng.random((2000, 3))
    exact = exact_winding(v, f, p)
    fast = SolidAngleTree(v, f)(p)
    assert np.abs(fast - exact).max() < TREE_TOLERANCE
    assert np.abs(fast - exact).mean() < 0.2 * TREE_TOLERANCE
    assert ((fast > 0.5) == (exact > 0.5)).mean() > 0.999
    # a coarser tree is faster and worse: the accuracy parameter is used
    assert np.abs(SolidAngleTree(v, f, beta=1.0)(p) - exact).max() > TREE_TOLERANCE


def test_is_closed_counts_each_edge_both_ways():
    s = trimesh.creation.icosphere(2, 5.0)
    f = np.asarray(s.faces)
    assert winding.is_closed(f)
    assert not winding.is_closed(f[1:])  # a hole
    flipped = f.copy()
    flipped[0] = flipped[0, ::-1]
    assert not winding.is_closed(flipped)  # one face wound the wrong way
    two = np.r_[f, f + f.max() + 1]
    assert winding.is_closed(two)  # several closed parts
    assert not winding.is_closed(np.zeros((0, 3), dtype=np.int64))


def test_column_winding_of_overlapping_closed_parts_is_exact():
    """Two overlapping closed spheres: the crossing count gives 2 in the overlap, 1 in
    one sphere, 0 outside, as the tree does, on every grid point off the surfaces."""
    a = trimesh.creation.icosphere(3, 10.0)
    b = trimesh.creation.icosphere(3, 10.0).apply_translation((8.0, 0, 0))
    m = trimesh.util.concatenate([a, b])
    wn = winding.Winding(m.vertices, m.faces)
    assert wn.closed
    axes = [np.arange(-13.0, 22.0, 1.3), np.arange(-12.0, 12.0, 1.3), np.arange(-12, 12.0, 1.1)]
    w = winding.grid_winding(wn, axes, np.ones(tuple(len(x) for x in axes), bool))
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    ra = np.linalg.norm(pts, axis=1)
    rb = np.linalg.norm(pts - (8.0, 0, 0), axis=1)
    off = (np.abs(ra - 10) > 0.3) & (np.abs(rb - 10) > 0.3)
    want = (ra < 10).astype(float) + (rb < 10)
    assert np.array_equal(w.ravel()[off], want[off])
    assert set(np.unique(w)) <= {0.0, 1.0, 2.0}
    assert np.abs(wn(pts[off]) - want[off]).max() < TREE_TOLERANCE


def test_column_through_a_vertex_is_evaluated_point_by_point():
    """A vertical line running exactly through the apex of a closed pyramid crosses its
    four sides there at once (and its base once): the count does not add up to zero, so
    that line's points are taken from the tree instead, and still come out 1 inside and
    0 outside; every other line is an exact count."""
    jx, jy = RAY_JITTER_MM  # the line through grid x = 0, y = 0
    v = np.array([[-5.0, -5, -5], [5, -5, -5], [5, 5, -5], [-5, 5, -5], [jx, jy, 5]])
    f = np.array([[0, 2, 1], [0, 3, 2], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    tri = v[f]
    assert np.einsum("ij,ij->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) > 0  # outward
    axes = [np.arange(-6.0, 6.1, 1.5)] * 2 + [np.arange(-7.25, 7.0, 1.5)]  # none on a face
    wn = winding.Winding(v, f)
    assert wn.closed
    w = winding.column_winding(wn, axes)
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    exact = exact_winding(v, f, pts).reshape(w.shape)
    i0 = int(np.argmin(np.abs(axes[0])))
    line = w[i0, i0]
    assert np.all(np.abs(line - exact[i0, i0]) < TREE_TOLERANCE)
    assert np.round(line).max() == 1 and np.round(line).min() == 0
    assert not np.all(np.isin(line, [0.0, 1.0]))  # from the tree, not a count
    rest = np.ones(w.shape[:2], bool)
    rest[i0, i0] = False
    assert np.array_equal(w[rest], np.round(exact[rest]))
    assert w[rest].max() == 1
