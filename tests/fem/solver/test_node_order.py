"""The rows' order found on their nodes (`fruitcli.fem.solver.node_order`,
`pardiso.node_order`): runs of alike rows, their graph and the expanded order exactly on
small matrices, PARDISO's perm convention by a star that factors without fill only in
the right order, and solves through the order equal to those without it."""

import numpy as np
import pytest
import scipy.sparse as sp

from fruitcli.fem.solver import node_order, pardiso
from fruitcli.fem.solver.linsolve import upper_triangle


def block_matrix(sizes: list[int], node_pairs: list[tuple[int, int]]) -> sp.csr_matrix:
    """A symmetric positive definite matrix over nodes of `sizes` rows each, every row
    of a node coupled to every row of its own node and of the nodes it is paired with."""
    starts = np.concatenate([[0], np.cumsum(sizes)])
    n = int(starts[-1])
    dense = np.zeros((n, n))
    for a, b in [(a, a) for a in range(len(sizes))] + node_pairs:
        dense[starts[a] : starts[a + 1], starts[b] : starts[b + 1]] = -1.0
        dense[starts[b] : starts[b + 1], starts[a] : starts[a + 1]] = -1.0
    dense += np.diag(np.abs(dense).sum(axis=1) + 1.0)  # diagonally dominant: SPD
    return sp.csr_matrix(dense)


def test_runs_are_the_nodes_rows_and_their_graph_the_nodes_graph():
    """Nodes of 3, 2 and 1 rows in a chain 0-1-2: runs start at rows 0, 3, 5 (then 6);
    the graph's upper triangle is 0: {0, 1}, 1: {1, 2}, 2: {2}."""
    k = block_matrix([3, 2, 1], [(0, 1), (1, 2)])
    starts = node_order.row_runs(k.indptr, k.indices)
    assert starts.tolist() == [0, 3, 5, 6]
    ptr, idx = node_order.run_graph(k.indptr, k.indices, starts)
    assert ptr.tolist() == [0, 2, 4, 5]
    assert idx.tolist() == [0, 1, 1, 2, 2]


def test_rows_alike_only_by_chance_are_one_run_and_unlike_rows_are_not():
    """Two nodes with the same neighbours make one run (their rows are alike); a
    tridiagonal matrix has no two rows alike: as many runs as rows."""
    k = block_matrix([1, 1, 1], [(0, 2), (1, 2), (0, 1)])  # every row sees every row
    assert node_order.row_runs(k.indptr, k.indices).tolist() == [0, 3]
    tri = sp.diags([-1.0, 3.0, -1.0], [-1, 0, 1], shape=(5, 5), format="csr")
    assert node_order.row_runs(tri.indptr, tri.indices).tolist() == [0, 1, 2, 3, 4, 5]


def test_expand_puts_each_runs_rows_where_its_run_goes():
    """Runs [0, 3), [3, 5), [5, 6) in the order 2, 0, 1: rows 5, 0, 1, 2, 3, 4."""
    starts = np.array([0, 3, 5, 6])
    assert node_order.expand(np.array([2, 0, 1]), starts).tolist() == [5, 0, 1, 2, 3, 4]


pardiso_only = pytest.mark.skipif(not pardiso.available(), reason="MKL PARDISO not installed")


@pardiso_only
def test_a_star_factors_without_fill_so_its_hub_went_last():
    """A hub node of 3 rows coupled to 12 leaf nodes of 2 rows (none coupled to another):
    eliminated last, the hub leaves no fill; eliminated first, it fills the whole
    triangle. The order's factor (iparm[17], PARDISO's count with its supernodes'
    storage: 136) is under a quarter of the reversed order's (730): the order's
    convention (PARDISO's perm) holds end to end."""
    sizes = [3] + [2] * 12
    k = block_matrix(sizes, [(0, b) for b in range(1, 13)])
    pardiso._LAST_ORDER.clear()
    order = pardiso.node_order(k)
    assert order is not None and sorted(order.tolist()) == list(range(k.shape[0]))
    assert sorted(order[-3:].tolist()) == [0, 1, 2]  # the hub's rows last
    upper = upper_triangle(k)
    fac = pardiso.Pardiso(upper, pardiso.SPD, order=order)
    hub_first = pardiso.Pardiso(upper, pardiso.SPD, order=order[::-1].copy())
    assert fac.iparm[17] < hub_first.iparm[17] / 4
    b = np.arange(k.shape[0], dtype=float)
    assert np.linalg.norm(k @ fac.solve(b) - b) < 1e-12 * np.linalg.norm(b)


@pardiso_only
def test_factors_with_and_without_the_node_order_solve_alike():
    """A 3D Laplacian with 3 rows per grid node (the Laplacian kron a 3 x 3 SPD block):
    `factorize_probed` orders it on its nodes (the order kept for the pattern) and
    solves as the factor ordered by PARDISO on its rows, to 1e-10."""
    one = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(6, 6))
    eye = sp.identity(6)
    grid = sp.kron(sp.kron(one, eye), eye) + sp.kron(sp.kron(eye, one), eye)
    grid = grid + sp.kron(sp.kron(eye, eye), one)
    block = np.array([[4.0, 1.0, 0.0], [1.0, 4.0, 1.0], [0.0, 1.0, 4.0]])
    k = sp.kron(grid, block).tocsr()
    k.sort_indices()
    pardiso._LAST_ORDER.clear()
    fac = pardiso.factorize_probed(k, upper_triangle(k))
    assert fac is not None and fac.perm is not None
    kept = pardiso.node_order(k)  # the pattern's order, kept: not found again
    assert kept is pardiso._LAST_ORDER[0][2] and np.array_equal(kept, fac.perm)
    plain = pardiso.factorize_upper(upper_triangle(k))
    assert plain.perm is None
    b = np.random.default_rng(3).standard_normal(k.shape[0])
    x = fac.solve(b)
    assert np.abs(x - plain.solve(b)).max() < 1e-10 * np.abs(x).max()
