"""The crossing's parts without a field solve: deformation maps, objects, the derived
equivalents and the table's offsets (mm)."""

from __future__ import annotations

import numpy as np
import pytest

from fruitcli.electrostatics import crossing, deform, equivalents
from fruitcli.electrostatics.touch_objects import OBJECTS


def _cloud(n=200, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform([-8, -6, -4], [8, 6, 3], (n, 3))


@pytest.mark.parametrize("axis", ["x", "y"])
def test_stretch_keeps_volume_and_stretches_the_axis(axis):
    """lambda along the axis, lambda^-1/2 across: det F = 1."""
    pts = np.eye(3)
    moved = deform.stretched(pts, axis, 0.3)
    a = deform.AXES[axis]
    assert moved[a, a] == pytest.approx(1.3)
    assert np.prod(np.diag(moved)) == pytest.approx(1.0)


def test_bend_keeps_the_neutral_plane_and_stretches_the_surface():
    """Along x at curvature k, neutral plane 1.5 mm under the surface: arc lengths on the
    neutral plane are kept, on the surface they grow by 1.5 k; y is untouched."""
    k, zn = np.pi / 48, 1.5
    x = np.linspace(-10, 10, 2001)
    for depth, strain in ((-zn, 0.0), (0.0, zn * k)):
        pts = np.stack([x, np.full_like(x, 2.0), np.full_like(x, depth)], axis=1)
        bent = deform.bent(pts, "x", k, zn)
        length = np.linalg.norm(np.diff(bent, axis=0), axis=1).sum()
        assert length == pytest.approx(20.0 * (1 + strain), rel=1e-6)
        assert np.allclose(bent[:, 1], 2.0)
    assert np.array_equal(deform.bent(_cloud(), "y", 0.0, zn), _cloud())


def test_glue_blend_keeps_the_crossing_and_moves_the_far_cell():
    pts = np.array([[0.0, 0.0, -2.0], [0.5, 0.5, 0.0], [10.0, 0.0, 0.0]])
    target = pts + 1.0
    moved = deform.deformed(pts, target, glue_mm=1.3, ramp_mm=6.0)
    assert np.allclose(moved[:2], pts[:2])
    assert np.allclose(moved[2], target[2])
    w = deform.blend(np.array([[1.3 + 3.0, 0, 0]]), 1.3, 6.0)
    assert w[0] == pytest.approx(0.5)


def test_objects_hold_their_shapes():
    """The small tip's hemisphere, the Allen key's flat end, placed at (dx, dy, gap)."""
    small, medium = OBJECTS["small"], OBJECTS["medium"]
    p = np.array(
        [
            [1.0, 2.0, 0.5],  # the tip's lowest point
            [1.0 + 1.4, 2.0, 0.5 + 1.5],  # on the cap's equator, inside
            [1.0 + 1.0, 2.0, 0.6],  # beside the tip, under the cap
            [1.0, 2.0, 0.49],
        ]
    )  # just under it
    assert small.contains(p, 1.0, 2.0, 0.5).tolist() == [True, True, False, False]
    q = np.array([[4.0, 0.0, 1.0], [4.1, 0.0, 1.0], [0.0, 0.0, 0.99], [0.0, 0.0, 9.0]])
    assert medium.contains(q, 0.0, 0.0, 1.0).tolist() == [True, False, False, True]


def test_offsets_reach_a_pitch_and_a_half_with_both_signs():
    assert np.allclose(crossing.offsets_mm(16.0), np.arange(-24.0, 24.5, 4.0))
    assert np.allclose(crossing.offsets_mm(12.0, steps=4), np.arange(-18.0, 18.1, 1.5))
    assert np.allclose(crossing.positions_mm(12.0), [0.0, 3.0, 6.0])


class _TranslatedSolver:
    """A cell whose crossing (i, j) sees law(X - i px, Y - j py) for an object at (X, Y)."""

    tx_names = ["tx-1", "tx", "tx+1"]
    rx_names = ["rx-1", "rx", "rx+1"]

    def __init__(self, law, px, py):
        self.law, self.px, self.py = law, px, py

    def crossings(self):
        return np.full((3, 3), 100.0)

    def object_crossings(self, name, x, y, gap):
        k = np.array([-1.0, 0.0, 1.0])
        return 100.0 + self.law(x - k[:, None] * self.px, y - k[None, :] * self.py, gap)


def test_touch_table_reads_each_offset_off_the_crossing_that_sees_it():
    def law(dx, dy, gap):
        return -np.exp(-(dx**2 / 50.0 + dy**2 / 30.0) - gap)

    spec = crossing.cell_spec(16.0, 12.0, 2.0, 0.6, 0.1, [0.0, 1.0])
    solver = _TranslatedSolver(law, 16.0, 12.0)
    dx, dy, dc, mismatch = crossing.touch_table(
        solver, spec, ["small"], [0.0, 1.0], solver.crossings()
    )
    assert np.allclose(dx, crossing.offsets_mm(16.0)) and np.allclose(dy, crossing.offsets_mm(12.0))
    gx, gy = np.meshgrid(dx, dy, indexing="ij")
    for g, gap in enumerate((0.0, 1.0)):
        assert np.allclose(dc[0, g], law(gx, gy, gap), rtol=0, atol=1e-12)
    assert mismatch == pytest.approx(0.0, abs=1e-12)


def test_footprint_fit_recovers_a_gaussian():
    dx, dy = np.array([0.0, 4.0, 8.0]), np.array([0.0, 3.0, 6.0])
    gx, gy = np.meshgrid(dx, dy, indexing="ij")
    drop = 50.0 * np.exp(-0.5 * (gx**2 + gy**2) / 6.5**2)
    assert equivalents.footprint_sigma_mm(dx, dy, drop) == pytest.approx(6.5, rel=1e-6)


def test_decay_gap_interpolates_and_extrapolates_an_exponential():
    gaps = np.array([0.0, 0.5, 1.0, 2.0, 4.0])
    drop = 80.0 * np.exp(-gaps / 1.7)
    assert equivalents.decay_gap_mm(gaps, drop, 80.0 / np.e) == pytest.approx(1.7, rel=1e-9)
    # 20 counts from 80 at decay 1.7: 1.7 ln 4 = 2.36 mm (inside); 2 counts: beyond the table
    assert equivalents.decay_gap_mm(gaps, drop, 20.0) == pytest.approx(1.7 * np.log(4))
    assert equivalents.decay_gap_mm(gaps, drop, 2.0) == pytest.approx(1.7 * np.log(40))
    assert equivalents.decay_gap_mm(gaps, drop, 100.0) == 0.0


def test_mesh_sizes_follow_the_insulation_within_their_range():
    gaps = [0.0, 1.0]
    thin = crossing.cell_spec(16, 12, 2.0, 0.6, 0.01, gaps)
    thick = crossing.cell_spec(16, 12, 2.0, 0.6, 0.5, gaps)
    assert thin.crossing_size_mm == pytest.approx(0.06)
    assert thick.crossing_size_mm == pytest.approx(0.1)
    assert thin.levels_mm == (1.0,)
    assert thin.points_mm == ()  # the objects are meshed by moving nodes
    assert thin.reach == 2 and thin.touch_box_mm == (8.0, 6.0)


@pytest.fixture(scope="module")
def small_cell():
    """A small crossing (pitch 6 x 5 mm, cover 1.5 mm, yarn 0.4 mm) and its solver."""
    from fruitcli.electrostatics.cell_mesh import mesh_cell

    spec = crossing.cell_spec(6.0, 5.0, 1.5, 0.4, 0.1, [0.0, 1.0])
    return crossing.CellSolver(mesh_cell(spec, 1, 60.0), 2.8)


def test_kept_pattern_solve_matches_a_plain_dirichlet_solve(small_cell):
    """C with an object's nodes held on the kept sparsity pattern equals the plain solve
    with those nodes removed, and the charges on all conductors sum to 0 (every outer
    face insulating)."""
    from fruitcli.electrostatics import capacitance

    s = small_cell
    obj = np.flatnonzero(OBJECTS["medium"].contains(s.mesh.nodes, 1.5, 0.0, 0.0) & s.air)
    assert obj.size > 0
    others = [n for n in (*s.tx_names, *s.rx_names) if n not in ("tx", "rx")]
    assert len(others) == 4  # the crossings a pitch away
    sides = np.concatenate([s.mesh.surfaces[n] for n in ("tx_side", "rx_side", *others)])
    plain = capacitance.mutual_capacitance(s.k, s.tx, s.rx, np.concatenate([sides, obj]))
    assert s.with_object("medium", 1.5, 0.0, 0.0) == pytest.approx(plain, rel=1e-9)
    c0 = s.capacitance()
    assert c0 == pytest.approx(capacitance.mutual_capacitance(s.k, s.tx, s.rx, sides), rel=1e-9)
    low = np.concatenate([s.rx, sides, obj])
    u = capacitance.solve_potential(
        s.k, np.concatenate([s.tx, low]), np.concatenate([np.ones(len(s.tx)), np.zeros(len(low))])
    )
    charges = [capacitance.conductor_charge(s.k, u, n) for n in (s.tx, s.rx, sides, obj)]
    assert abs(sum(charges)) < 1e-8 * charges[0]
    assert 0 < plain < c0  # the grounded object takes field from Rx


def test_the_cell_is_finer_where_the_objects_touch(small_cell):
    """The air's tets just above the touch box are at the contact size
    (`cell_geometry.CONTACT_SIZE_FACTOR` of the surface size), finer than those at the
    same height a pitch and more away."""
    mesh = small_cell.mesh
    air = np.array(mesh.regions)[mesh.region] == "air"
    x = mesh.nodes[mesh.tets[:, :4]]
    centre = x.mean(axis=1)
    edge = np.linalg.norm(x[:, 1:] - x[:, :1], axis=2).mean(axis=1)
    low = air & (centre[:, 2] < 0.5)
    over = low & (centre[:, 0] > 0) & (centre[:, 0] < 3) & (centre[:, 1] > 0) & (centre[:, 1] < 2.5)
    away = low & (centre[:, 0] > 9)
    size = crossing.SURFACE_SIZE_MM
    assert over.sum() > 50 and away.sum() > 50
    assert np.median(edge[over]) < 0.8 * size  # gmsh's edges run about 1.25 times its size
    assert np.median(edge[over]) < 0.75 * np.median(edge[away]), np.median(edge[away])


def test_deformed_cell_is_solved_and_restored(small_cell):
    """C of a moved cell, then the cell at rest again gives C0 back; no motion, no change."""
    s = small_cell
    c0 = s.capacitance()
    nodes = s.mesh.nodes
    moved = deform.deformed(nodes, deform.stretched(nodes, "y", 0.2), 0.9, 2.5)
    c_moved = s.capacitance(nodes=moved)
    assert c_moved != pytest.approx(c0, rel=1e-6)
    assert s.capacitance(nodes=nodes) == pytest.approx(c0, rel=1e-12)
    assert s.capacitance(nodes=deform.deformed(nodes, nodes, 0.9, 2.5)) == pytest.approx(
        c0, rel=1e-12
    )
    s.capacitance(nodes=nodes)


def _table(c_bend_ff):
    gaps = np.array([0.0, 1.0, 2.0])
    dx, dy = crossing.offsets_mm(16.0), crossing.offsets_mm(12.0)
    gx, gy = np.meshgrid(dx, dy, indexing="ij")
    dc = -40.0 * np.exp(-gaps / 2.0)[:, None, None] * np.exp(-0.5 * (gx**2 + gy**2) / 36)
    return crossing.CrossingTable(
        800.0,
        ["small"],
        gaps,
        dx,
        dy,
        dc[None],
        ["stretch_x", "stretch_y", "bend_x", "bend_y"],
        np.array([0.0, 0.1]),
        np.array([0.0, crossing.PAD_BEND_CURVATURE_PER_MM]),
        np.full((2, 2), 800.0),
        np.asarray(c_bend_ff, float),
    )


def test_counts_per_ff_sets_the_larger_bend_shift_to_ten_counts():
    """Bent as the pad, +2 fF along x and -5 fF along y: 10 counts / 5 fF = 2 counts/fF;
    then the contact activation is 2 * 40 = 80 counts, the footprint sigma 6 mm, the gap
    decay 2 mm and the threshold of 20 counts is crossed at 2 ln 4 mm."""
    table = _table([[800.0, 802.0], [800.0, 795.0]])
    scale, fit = equivalents.counts_per_ff(table)
    assert scale == pytest.approx(2.0)
    assert fit["deformation"] == "bend_y" and fit["shift_ff"] == pytest.approx(-5.0)
    summary = equivalents.summarize(table)
    small = summary["objects"]["small"]
    assert small["contact_counts"] == pytest.approx(80.0)
    assert small["footprint_sigma_mm"] == pytest.approx(6.0, rel=1e-6)
    assert small["gap_decay_mm"] == pytest.approx(2.0)
    assert small["threshold_gap_mm"] == pytest.approx(2 * np.log(4))
    assert small["extrapolated"] == ["threshold_gap_mm"]
    assert summary["deformation_shift_counts"]["bend_y"] == pytest.approx([0.0, 10.0])
    assert summary["deformation_shift_counts"]["bend_x"] == pytest.approx([0.0, -4.0])


def test_counts_per_ff_refuses_a_bend_without_shift():
    from fruitcli.errors import SolverError

    with pytest.raises(SolverError, match="bent pad"):
        equivalents.counts_per_ff(_table([[800.0, 800.0], [800.0, 800.0]]))


def test_kept_pattern_solve_without_pardiso(small_cell, monkeypatch):
    """Without MKL (the default install) the crossing's solves take SciPy's factorization:
    the same C0 and C with an object as with PARDISO."""
    from fruitcli.fem.solver import pardiso

    s = small_cell
    c0, c_obj = s.capacitance(), s.with_object("medium", 1.5, 0.0, 0.0)
    monkeypatch.setattr(pardiso, "_MISSING", True)
    assert s.capacitance() == pytest.approx(c0, rel=1e-9)
    assert s.with_object("medium", 1.5, 0.0, 0.0) == pytest.approx(c_obj, rel=1e-9)


def test_glue_and_neutral_plane_move_the_deformation_table(small_cell):
    """A glue radius wider than the cell keeps every node still: C stays C0 under each
    stretch and bend; the default glue shifts C, and bending about another neutral
    plane changes the bend's C but not the stretch's."""
    s = small_cell
    c0 = s.capacitance()
    spec = crossing.cell_spec(6.0, 5.0, 1.5, 0.4, 0.1, [0.0, 1.0])
    _, c_s, _, c_b = crossing.deformation_table(s, spec, c0, glue_mm=100.0)
    assert np.allclose(c_s, c0, rtol=1e-9) and np.allclose(c_b, c0, rtol=1e-9)
    _, d_s, _, d_b = crossing.deformation_table(s, spec, c0)
    _, n_s, _, n_b = crossing.deformation_table(s, spec, c0, neutral_mm=0.5)
    assert not np.allclose(d_b[:, 1:], c0, rtol=1e-6)
    assert np.allclose(n_s, d_s, rtol=1e-12)
    assert not np.allclose(n_b[:, 1:], d_b[:, 1:], rtol=1e-6)
    assert s.capacitance() == pytest.approx(c0, rel=1e-12)  # the cell at rest again
