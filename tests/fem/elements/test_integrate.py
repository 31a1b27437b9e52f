"""The hyperelastic element loop (`fruitcli.fem.elements.integrate.evaluate`) on a
configuration that inverts one quadratic tet: that element's tangent block is written
as zeros whatever the blocks array held before, and every other element's block is the
one it has in a loop where nothing inverts (the same state without the inverted tet,
and, for the elements the inversion leaves alone, the state before it)."""

import numpy as np
import pytest

from fruitcli.fem.continuum import reference_gradients
from fruitcli.fem.element_sums import node_incidence
from fruitcli.fem.elements.integrate import evaluate
from fruitcli.fem.elements.lagrange import ELEMENTS, TET10_EDGES
from fruitcli.fem.elements.quadratic import quadratic_mesh
from fruitcli.fem.materials.build import material
from fruitcli.fem.meshing.grid import structured_box

MOVED = 1  # corner node (4, 0, 0) mm of the 2 x 1 x 1 box, a corner of tets 8 and 10 only
FLIPPED = 8  # the tet MOVED is mirrored through


def box() -> tuple[np.ndarray, np.ndarray]:
    """(nodes (n, 3) mm, conn (12, 10)): two cubes of 2 mm in quadratic tets."""
    nodes, tets = structured_box([0, 0, 0], [4, 2, 2], (2, 1, 1))
    nodes2, conn, _ = quadratic_mesh(nodes, tets, [])
    return nodes2, conn


def inverting(x: np.ndarray, conn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x with MOVED pushed through FLIPPED's opposite face to half FLIPPED's height
    beyond it and the edge nodes of its edges at their midpoints, the nodes moved):
    FLIPPED's volume changes sign, its neighbour across MOVED only shears."""
    y = x.copy()
    face = y[[n for n in conn[FLIPPED, :4] if n != MOVED]]
    normal = np.cross(face[1] - face[0], face[2] - face[0])
    normal /= np.linalg.norm(normal)
    y[MOVED] -= 1.5 * np.dot(y[MOVED] - face[0], normal) * normal
    moved = [MOVED]
    for tet in conn:
        for k, (a, b) in enumerate(TET10_EDGES):
            if MOVED in (tet[a], tet[b]):
                y[tet[4 + k]] = 0.5 * (y[tet[a]] + y[tet[b]])
                moved.append(tet[4 + k])
    return y, np.unique(moved)


def element_loop(
    x: np.ndarray, nodes: np.ndarray, conn: np.ndarray, element: str, blocks: np.ndarray
) -> tuple[float, np.ndarray]:
    """(energy or -1.0, smallest det F per element) from the loop at x, its tangents
    written into blocks (m, 30, 30)."""
    fam = ELEMENTS[element]
    dn, wq = reference_gradients(nodes, conn, fam)
    consts = material("neo-hookean", 100.0, 0.49).constants()
    forces = np.zeros_like(x)
    jmin = np.empty(len(conn))
    ptr, rows = node_incidence(conn, len(x))
    energy = evaluate(
        x, conn, dn, wq, consts, fam.mean_dilatation, True, forces, blocks, jmin, ptr, rows
    )
    return energy, jmin


@pytest.mark.parametrize("element", ["p2", "p2-pure"])
def test_an_inverted_element_gets_a_zero_tangent_block_the_others_their_own(element):
    nodes, conn = box()
    rng = np.random.default_rng(7)
    x = nodes + 0.02 * rng.standard_normal(nodes.shape)  # every block distinct from rest's
    y, moved = inverting(x, conn)
    shape = (len(conn), 30, 30)
    before = np.empty(shape)
    energy_x, jmin_x = element_loop(x, nodes, conn, element, before)
    assert energy_x > 0.0 and (jmin_x > 0.0).all() and np.isfinite(before).all()
    for stale in (np.nan, 1.0):  # a fresh array's garbage, a reused array's old values
        after = np.full(shape, stale)
        energy_y, jmin_y = element_loop(y, nodes, conn, element, after)
        assert energy_y == -1.0
        assert np.flatnonzero(jmin_y <= 0.0).tolist() == [FLIPPED]
        assert np.all(after[FLIPPED] == 0.0)
        touched = np.isin(conn, moved).any(axis=1)
        assert touched.sum() == 2  # FLIPPED and its neighbour across MOVED
        kept = ~touched
        assert np.array_equal(after[kept], before[kept])
        neighbour = np.flatnonzero(touched & (np.arange(len(conn)) != FLIPPED))
        assert not np.array_equal(after[neighbour], before[neighbour])
        others = np.delete(conn, FLIPPED, axis=0)  # the same state, nothing inverted
        alone = np.empty((len(others), 30, 30))
        energy_o, jmin_o = element_loop(y, nodes, others, element, alone)
        assert energy_o > 0.0 and (jmin_o > 0.0).all() and np.isfinite(alone).all()
        assert np.array_equal(np.delete(after, FLIPPED, axis=0), alone)
