"""The CSR pattern of the free dofs (`assemble.CsrPattern`): built from the node pairs
that share an element, it equals the one read off every dof pair, and assembling with
it equals SciPy's sum of the element blocks."""

import numpy as np
import pytest
import scipy.sparse as sp

from fruitcli.fem.meshing.grid import structured_box
from fruitcli.fem.solver.assemble import CsrPattern, element_dofs


def dof_pairs_pattern(tets, n_nodes, free_mask):
    """(indptr, indices, entry_slot, diag_slot) from every element's dof pairs and the
    free dofs' diagonal, sorted by (row, column): the definition of the pattern."""
    free = np.flatnonzero(free_mask)
    new = np.full(3 * n_nodes, -1)
    new[free] = np.arange(len(free))
    dofs = element_dofs(tets)
    d = dofs.shape[1]
    rows = new[np.repeat(dofs, d, axis=1)].ravel()
    cols = new[np.tile(dofs, (1, d))].ravel()
    keep = (rows >= 0) & (cols >= 0)
    n = len(free)
    key = np.concatenate([rows[keep] * n + cols[keep], np.arange(n) * (n + 1)])
    uniq, inverse = np.unique(key, return_inverse=True)
    indptr = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(uniq // n, minlength=n), out=indptr[1:])
    slot = np.full(len(keep), -1)
    slot[keep] = inverse[: keep.sum()]
    return indptr, uniq % n, slot, inverse[keep.sum() :]


def quadratic_box():
    """A 3 x 2 x 2 box of tets with 6 extra node numbers per tet (edge nodes as the
    quadratic element numbers them: shared between the tets of an edge) and one node
    in no element."""
    nodes, tets = structured_box([0, 0, 0], [3, 2, 2], (3, 2, 2))
    pairs = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]
    edges = np.sort(np.stack([tets[:, [a, b]] for a, b in pairs], axis=1), axis=2)
    uniq, edge_of = np.unique(edges.reshape(-1, 2), axis=0, return_inverse=True)
    conn = np.hstack([tets, len(nodes) + edge_of.reshape(len(tets), 6)])
    return conn, len(nodes) + len(uniq) + 1


@pytest.mark.parametrize("quadratic", [False, True])
def test_pattern_equals_the_dof_pairs_pattern_and_assembles_like_scipy(quadratic):
    """With a third of the dofs fixed at random (and none), indptr, indices, each
    element entry's slot and each diagonal's slot equal the dof-pair definition's, and
    the assembled matrix equals SciPy's COO sum of the blocks (plus a diagonal)."""
    if quadratic:
        conn, n_nodes = quadratic_box()
    else:
        nodes, conn = structured_box([0, 0, 0], [3, 2, 2], (3, 2, 2))
        n_nodes = len(nodes)
    rng = np.random.default_rng(4)
    for free_mask in (rng.random(3 * n_nodes) > 0.33, np.ones(3 * n_nodes, bool)):
        pattern = CsrPattern.build(conn, n_nodes, free_mask)
        indptr, indices, slot, diag = dof_pairs_pattern(conn, n_nodes, free_mask)
        assert np.array_equal(pattern.indptr, indptr)
        assert np.array_equal(pattern.indices, indices)
        assert np.array_equal(pattern.entry_slot, slot)
        assert np.array_equal(pattern.diag_slot, diag)
        d = 3 * conn.shape[1]
        blocks = rng.standard_normal((len(conn), d, d))
        diagonal = rng.standard_normal(len(pattern.free))
        got = pattern.assemble(blocks, diagonal)
        dofs = element_dofs(conn)
        full = sp.coo_matrix(
            (blocks.ravel(), (np.repeat(dofs, d, axis=1).ravel(), np.tile(dofs, (1, d)).ravel())),
            shape=(3 * n_nodes, 3 * n_nodes),
        ).tocsr()[free_mask][:, free_mask] + sp.diags(diagonal)
        assert abs(got - full).max() < 1e-12 * abs(full).max()


def test_upper_triangle_is_scipys_for_new_and_repeated_patterns():
    """`upper_triangle` of CSR matrices gives scipy's `triu` exactly, of the input's class:
    for a pattern, for new values on the same pattern (the kept pick, reused), for
    another pattern, a csr_array, a matrix with unsorted indices, one with duplicate
    entries and one whose sorted flag is wrong; the kept pick's arrays are read-only."""
    from fruitcli.fem.solver import linsolve
    from fruitcli.fem.solver.linsolve import upper_triangle

    rng = np.random.default_rng(4)

    def symmetric(n, density):
        a = sp.random(n, n, density=density, random_state=rng, format="csr")
        return (a + a.T + sp.identity(n)).tocsr()

    k = symmetric(60, 0.1)
    again = k.copy()
    again.data = rng.normal(size=again.nnz)
    other = symmetric(45, 0.2)
    rows = [k.indices[a:b][::-1] for a, b in zip(k.indptr[:-1], k.indptr[1:], strict=True)]
    unsorted = sp.csr_matrix((k.data.copy(), np.concatenate(rows), k.indptr.copy()), k.shape)
    twice = sp.csr_matrix(
        (np.array([1.0, 2.0, 3.0, 4.0]), np.array([0, 1, 1, 1]), np.array([0, 3, 4])), (2, 2)
    )
    lying, lying_twice = unsorted.copy(), twice.copy()
    for m in (lying, lying_twice):  # flags that are wrong
        m.has_canonical_format = True
    for m in (k, again, other, sp.csr_array(k), k, unsorted, twice, lying, lying_twice):
        u, want = upper_triangle(m), sp.triu(m, format="csr")
        want.sum_duplicates()
        assert type(u) is type(m)
        assert np.array_equal(u.indptr, want.indptr)
        assert np.array_equal(u.indices, want.indices)
        assert np.array_equal(u.data, want.data)
    kept = linsolve._UPPER_PICK[0]
    upper_triangle(again)
    assert linsolve._UPPER_PICK[0] is kept  # the same pattern: the same pick
    assert not upper_triangle(again).indices.flags.writeable
