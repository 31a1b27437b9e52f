"""Unit tests of the geometry building blocks against closed forms."""

import numpy as np
import pytest
import trimesh

from fruitcli.geometry.mesh.columns import inside_columns, top_z, vertical_hits
from fruitcli.geometry.mesh.distance import (
    SurfaceDistance,
    TreeDistance,
    closest_on_triangles,
    grid_vertex_distance,
)
from fruitcli.geometry.tracks.sections import section_pieces
from fruitcli.geometry.tracks.taxels import piece_crossings
from fruitcli.geometry.tracks.tubes import resample, track_polylines, tube_arrays


def test_closest_on_triangle_regions():
    a, b, c = np.array([0.0, 0, 0]), np.array([2.0, 0, 0]), np.array([0.0, 2, 0])
    p = np.array(
        [
            [0.5, 0.5, 3.0],  # above the interior -> its projection
            [-1.0, -1.0, 0.0],  # beyond vertex a
            [3.0, -1.0, 1.0],  # beyond vertex b
            [1.0, -2.0, 0.0],  # beyond edge ab
            [2.0, 2.0, 0.0],
        ]
    )  # beyond edge bc
    n = len(p)
    q = closest_on_triangles(p, np.tile(a, (n, 1)), np.tile(b, (n, 1)), np.tile(c, (n, 1)))
    expect = [[0.5, 0.5, 0], [0, 0, 0], [2, 0, 0], [1, 0, 0], [1, 1, 0]]
    assert np.allclose(q, expect)


def test_surface_distance_sphere():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=10.0)
    pts = np.array([[0.0, 0, 0], [0, 0, 15.0], [3.0, 4.0, 0], [0, 20.0, 0]])
    _, d, _ = SurfaceDistance(sphere.vertices, sphere.faces).closest(pts)
    # the polyhedron lies inside the sphere by at most its sagitta (~0.04 mm here)
    assert np.allclose(d, [10, 5, 5, 10], atol=0.05)


def test_tree_distance_is_the_brute_force_minimum():
    """Exact whatever the triangles: a sphere, and a long box of 12 triangles (points
    far from every corner of its long faces), against the minimum over all triangles;
    the face returned is one of the nearest."""
    rng = np.random.default_rng(5)
    for mesh in (
        trimesh.creation.icosphere(3, 10.0),
        trimesh.creation.box(extents=(200.0, 4.0, 3.0)),
    ):
        v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        lo, hi = v.min(axis=0) - 5, v.max(axis=0) + 5
        p = lo + (hi - lo) * rng.random((400, 3))
        tri = v[f]
        q_all = np.stack(
            [
                closest_on_triangles(np.tile(x, (len(f), 1)), tri[:, 0], tri[:, 1], tri[:, 2])
                for x in p
            ]
        )
        d_all = np.linalg.norm(q_all - p[:, None, :], axis=2)
        q, d, face = TreeDistance(v, f).closest(p)
        assert np.allclose(d, d_all.min(axis=1), rtol=0, atol=1e-9)
        assert np.allclose(np.linalg.norm(q - p, axis=1), d, atol=1e-9)
        best = d_all <= d_all.min(axis=1, keepdims=True) + 1e-9
        assert best[np.arange(len(p)), face].all()
    _, d, face = TreeDistance(v, f).closest(np.zeros((0, 3)))
    assert len(d) == 0 and len(face) == 0


def test_grid_vertex_distance_is_the_bounded_kd_tree_query():
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(2)
    v = rng.normal(size=(500, 3)) * (10.0, 6.0, 4.0)
    axes = [np.arange(-30.0, 30.0, 1.3), np.arange(-20.0, 21.0, 1.3), np.arange(-12.0, 12.0, 1.3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    for upper in (2.5, 6.0):
        want = cKDTree(v).query(pts, distance_upper_bound=upper)[0]
        got = grid_vertex_distance(v, axes, upper)
        assert np.isinf(want).any() and np.isfinite(want).any()
        assert np.array_equal(np.isinf(got), np.isinf(want))
        assert np.allclose(got[np.isfinite(want)], want[np.isfinite(want)], rtol=0, atol=1e-12)


def test_top_z_and_parity_on_a_box():
    box = trimesh.creation.box(extents=(4.0, 6.0, 2.0))  # z from -1 to 1
    xy = np.array([[0.3, 0.7], [1.9, -2.9], [5.0, 0.0]])
    z = top_z(box.vertices, box.faces, xy)
    assert np.allclose(z[:2], 1.0) and np.isnan(z[2])
    pi, zh = vertical_hits(box.vertices, box.faces, xy)
    assert np.array_equal(pi, [0, 0, 1, 1]) and np.allclose(zh, [-1, 1, -1, 1])
    inside = inside_columns(box.vertices, box.faces, xy, np.array([-2.0, -0.5, 0.5, 2.0]))
    assert inside.tolist() == [[False, True, True, False], [False, True, True, False], [False] * 4]


def test_sphere_section_is_a_circle():
    r = 10.0
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=r)
    pieces = section_pieces(sphere.vertices, sphere.faces, 0, 6.0)
    assert len(pieces) == 1 and pieces[0].closed
    rho = np.sqrt(r**2 - 36.0)
    assert abs(pieces[0].length_mm - 2 * np.pi * rho) < 0.01 * 2 * np.pi * rho
    assert np.allclose(pieces[0].points[:, 0], 6.0)
    # only the upper half: one open arc from z ~ 0 over the top
    up = sphere.triangles_center[:, 2] > 0
    arcs = section_pieces(sphere.vertices, sphere.faces, 0, 6.0, up)
    assert len(arcs) == 1 and not arcs[0].closed
    assert abs(arcs[0].length_mm - np.pi * rho) < 0.05 * np.pi * rho
    # crossing it with y = 0 gives the top point (6, 0, rho) on a face of the sphere
    lidx, pts, _ = piece_crossings(arcs[0], 1, np.array([0.0, 100.0]))
    assert lidx.tolist() == [0] and abs(pts[0, 2] - rho) < 0.05 and pts[0, 1] == 0.0


def test_box_section_through_vertices_is_its_perimeter():
    box = trimesh.creation.box(extents=(4.0, 6.0, 2.0))
    pieces = section_pieces(box.vertices, box.faces, 1, 0.0)
    assert len(pieces) == 1 and pieces[0].closed
    assert abs(pieces[0].length_mm - 2 * (4.0 + 2.0)) < 1e-9


def test_tube_volume_and_closedness():
    line = np.c_[np.linspace(0, 20, 7), np.zeros(7), np.zeros(7)]
    v, f = tube_arrays(line, 0.6, step_mm=1.0, ring=12)
    mesh = trimesh.Trimesh(v, f, process=True)
    assert mesh.is_watertight and mesh.volume > 0
    # a 12-gon of circumradius r has area 3 r^2
    assert mesh.volume == pytest.approx(3 * 0.36 * 20.0, rel=1e-9)
    arc = np.c_[
        10 * np.cos(np.linspace(0, np.pi, 50)), 10 * np.sin(np.linspace(0, np.pi, 50)), np.zeros(50)
    ]
    v, f = tube_arrays(arc, 0.5)
    assert trimesh.Trimesh(v, f).is_watertight
    assert len(resample(arc, 1.0)) == 33


def test_closed_loop_becomes_two_overlapping_tubes():
    t = np.linspace(0, 2 * np.pi, 41)
    loop = np.c_[np.cos(t), np.sin(t), 0 * t]
    loop[-1] = loop[0]
    halves = track_polylines(loop, closed=True)
    assert len(halves) == 2 and len(halves[0]) + len(halves[1]) > len(loop)


def test_masked_runs_bridges_short_gaps_and_drops_short_parts():
    from fruitcli.geometry.tracks.sections import Piece, masked_runs

    x = np.arange(21, dtype=float)  # 20 segments of 1 mm along x
    piece = Piece(np.c_[x, 0 * x, 0 * x], np.arange(20), False)
    keep = np.ones(20, dtype=bool)
    keep[8] = False  # a 1 mm gap: bridged
    keep[:2] = False  # a leading gap: dropped
    keep[17] = False  # leaves a 2 mm tail: too short
    keep[16] = False
    out = masked_runs(piece, keep, max_gap_mm=1.5, min_length_mm=2.5)
    assert len(out) == 1
    assert out[0].points[0, 0] == 2.0 and out[0].points[-1, 0] == 16.0
    # a closed loop with one short gap stays one closed piece
    t = np.linspace(0, 2 * np.pi, 41)
    loop = Piece(np.c_[np.cos(t), np.sin(t), 0 * t] * 10, np.arange(40), True)
    keep = np.ones(40, dtype=bool)
    keep[5] = False
    assert [p.closed for p in masked_runs(loop, keep, 2.0, 1.0)] == [True]
    # a long gap opens it into one arc that runs across the loop's seam
    keep[3:20] = False
    arcs = masked_runs(loop, keep, 2.0, 1.0)
    assert len(arcs) == 1 and not arcs[0].closed and len(arcs[0].points) == 24


def test_orient_faces_without_networkx():
    from fruitcli.geometry.mesh.load import orient_faces

    s = trimesh.creation.icosphere(3, 10.0)
    f = s.faces.copy()
    f[::3] = f[::3, ::-1]
    out, conflicts = orient_faces(f)
    assert conflicts == 0
    assert trimesh.Trimesh(s.vertices, out, process=False).is_winding_consistent
    assert (out[0] == f[0]).all()  # the first face keeps its winding
    # an open surface (a hemisphere) with every other face flipped: made consistent too
    keep = s.triangles_center[:, 2] > 0
    out, conflicts = orient_faces(f[keep])
    assert conflicts == 0
    assert trimesh.Trimesh(s.vertices, out, process=False).is_winding_consistent


def test_densify_splits_long_triangles_only():
    from fruitcli.geometry.tracks.densify import densify

    box = trimesh.creation.box(extents=(40.0, 30.0, 20.0))
    v, f, edge = densify(box.vertices, box.faces, 5.0)
    m = trimesh.Trimesh(v, f)
    assert edge == 5.0 and m.is_watertight and m.volume == pytest.approx(24000.0)
    assert np.linalg.norm(v[f] - v[f[:, [1, 2, 0]]], axis=2).max() <= 5.0
    assert densify(v, f, 5.0)[2] is None


def test_densify_cuts_long_strips_along_their_length_only():
    from fruitcli.geometry.tracks.densify import densify

    # a column's side: 128 strips 150 mm x 0.79 mm; cutting each face in four until the
    # 150 mm edges were short cut the strips across as well (281k faces, 0.006 mm edges)
    col = trimesh.creation.cylinder(radius=8.0, height=150.0, sections=64)
    v, f, edge = densify(col.vertices, col.faces, 2.2)
    m = trimesh.Trimesh(v, f, process=False)
    assert m.is_watertight and m.is_winding_consistent
    assert m.volume == pytest.approx(col.volume, rel=1e-9)
    lengths = np.linalg.norm(v[f] - v[f[:, [1, 2, 0]]], axis=2)
    assert edge == 2.2 and lengths.max() <= 2.2
    # about 2 L / edge faces per strip: 128 * 2 * 150 / 2.2 = 17.5k
    assert len(f) < 22_000
    # a face cap relaxes the edge length instead
    v, f, edge = densify(col.vertices, col.faces, 2.2, max_faces=5000)
    assert len(f) <= 5000 and edge > 2.2
    assert np.linalg.norm(v[f] - v[f[:, [1, 2, 0]]], axis=2).max() <= edge
    assert trimesh.Trimesh(v, f, process=False).is_watertight


def test_weld_merges_what_a_reader_merges(tmp_path):
    from fruitcli.geometry.mesh.export import weld_float32, write_stl

    # a tetrahedron whose fourth corner appears twice, 2e-9 mm apart, joined by two needle
    # faces (as a boolean left them where a tube ended on a wall): an STL reader merges the
    # two corners and sees two collapsed faces (2 bodies, not watertight), so the weld must
    # merge them too
    v = np.array(
        [
            [0.0, 0, 0],
            [10.0, 0, 0],
            [0.0, 10, 0],
            [0.003876361763, -5.98, 1.8],
            [0.003876359668, -5.98, 1.8],
        ]
    )
    f = np.array([[0, 2, 1], [0, 1, 3], [1, 4, 3], [1, 2, 4], [2, 0, 4], [0, 3, 4]])
    assert trimesh.Trimesh(v, f, process=False).is_watertight
    wv, wf = weld_float32(v, f)
    assert len(wv) == 4 and len(wf) == 4
    assert write_stl(tmp_path / "t.stl", v, f) == (True, 1)
