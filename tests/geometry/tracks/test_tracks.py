"""make-tracks end to end: shapes made here, the default Fruit, bad inputs via the CLI."""

import json

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import GeometryError
from fruitcli.geometry.mesh.columns import vertical_hits
from fruitcli.geometry.mesh.distance import SurfaceDistance, closest_on_triangles
from fruitcli.geometry.tracks.make_tracks import SCENE_NAMES, make_tracks
from fruitcli.tables import read_taxels

ON_SURFACE_MM = 0.01


def ellipsoid(path, radii=(40.0, 30.0, 20.0)):
    m = trimesh.creation.icosphere(subdivisions=5, radius=1.0)
    m.apply_scale(radii)
    m.export(path)
    return path


def load_stl(path):
    return trimesh.load_mesh(path, process=True)


@pytest.fixture(scope="module")
def ellipsoid_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("ell")
    art = ellipsoid(d / "ell.stl")
    report = make_tracks(art, d / "out", faces=3000)
    return d / "out", report


def test_outputs_and_report(ellipsoid_run):
    out, report = ellipsoid_run
    names = sorted(p.name for p in out.iterdir())
    assert names == [
        "preview.png",
        "reduced.stl",
        "report.json",
        "taxels.csv",
        "tracked_top.stl",
        "tracks.csv",
        "tracks.stl",
    ]
    saved = json.loads((out / "report.json").read_text())
    assert saved["taxels"] == report["taxels"] > 10
    assert set(saved["times_s"]) >= {"load", "reduce", "sections", "taxels", "tracks", "total"}
    reduced = load_stl(out / "reduced.stl")
    assert reduced.is_watertight and reduced.is_winding_consistent
    assert abs(len(reduced.faces) - 3000) < 300
    # the offset of an ellipsoid with semi-axes a, b, c by 2 mm spans a-2, b-2, c-2
    assert np.allclose(reduced.extents, [76, 56, 36], atol=0.3)
    assert report["offset_error"]["hausdorff_mm"] < 0.5
    assert report["tracked_top_reloads_watertight"]
    # the split plane of an ellipsoid is its equator z = 0 (within one grid cell)
    assert abs(report["split_z_mm"]) <= report["distance_grid_mm"]


def test_taxels_on_surface_and_planes(ellipsoid_run):
    out, report = ellipsoid_run
    tx = read_taxels(out / "taxels.csv")
    assert np.array_equal(tx.ids, np.arange(len(tx.ids)))
    assert tx.i.min() == 0 and tx.j.min() == 0
    x0, y0 = report["grid"]["origin_mm"]
    assert np.allclose(tx.xyz_mm[:, 0], x0 + 16.0 * tx.i, atol=1e-5)
    assert np.allclose(tx.xyz_mm[:, 1], y0 + 12.0 * tx.j, atol=1e-5)
    reduced = load_stl(out / "reduced.stl")
    _, d, _ = SurfaceDistance(reduced.vertices, reduced.faces).closest(tx.xyz_mm)
    assert d.max() <= ON_SURFACE_MM
    assert np.allclose(np.linalg.norm(tx.normals, axis=1), 1.0, atol=1e-5)
    assert (tx.normals[:, 2] > 0).all()
    # the outward normal of the ellipsoid (x/a^2, y/b^2, z/c^2), a..c reduced by 2 mm
    p = tx.xyz_mm
    n = p / np.array([38.0, 28.0, 18.0]) ** 2
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.degrees(np.arccos(np.clip((n * tx.normals).sum(1), -1, 1))).max() < 5.0
    # centred grid: about symmetric about x = 0 and y = 0 (the reduced mesh is not exactly)
    assert abs(p[:, 0].min() + p[:, 0].max()) < 0.5 and abs(p[:, 1].min() + p[:, 1].max()) < 0.5


def test_tracked_piece_is_one_closed_volume(ellipsoid_run):
    out, report = ellipsoid_run
    v = report["volume_mm3"]
    assert 0 < v["reduced_top"] - v["tracked_top"] < 0.05 * v["reduced_top"]
    # reduced top is about half the reduced ellipsoid, 4/3 pi abc / 2
    assert v["reduced_top"] == pytest.approx(2 / 3 * np.pi * 38 * 28 * 18, rel=0.03)


def test_default_fruit_end_to_end(tmp_path):
    from fruitcli.geometry.artist import FRUIT_CHAMBERS, write_artist

    art = tmp_path / "fruit.ply"
    info = write_artist(art)
    assert info["triangles"] >= 100_000
    report = make_tracks(art, tmp_path / "out")
    assert 35 <= report["taxels"] <= 60
    reduced = load_stl(tmp_path / "out" / "reduced.stl")
    dist = SurfaceDistance(reduced.vertices, reduced.faces)
    u, w = np.meshgrid(np.linspace(0, np.pi, 25), np.linspace(0, 2 * np.pi, 48))
    unit = np.c_[
        (np.sin(u) * np.cos(w)).ravel(), (np.sin(u) * np.sin(w)).ravel(), np.cos(u).ravel()
    ]
    for k, ch in enumerate(FRUIT_CHAMBERS):
        c, r = np.array(ch["center_mm"]), np.array(ch["radii_mm"])
        pts = c + unit * r
        _, d, _ = dist.closest(pts)
        assert d.min() >= 3.0, ch["name"]
        pi, zh = vertical_hits(reduced.vertices, reduced.faces, pts)
        above = np.bincount(pi[zh > pts[pi, 2]], minlength=len(pts))
        assert (above % 2 == 1).all(), ch["name"]  # inside the reduced body
        for other in FRUIT_CHAMBERS[k + 1 :]:
            q = (pts - np.array(other["center_mm"])) / np.array(other["radii_mm"])
            assert ((q**2).sum(1) > 1).all()


def _cli(args):
    return CliRunner().invoke(cli, args)


def _assert_refused(result, out, *words):
    assert result.exit_code == 1, result.output
    line = result.output.strip().splitlines()[-1]
    assert line.startswith("Error:")
    for w in words:
        assert w in line, line
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize(
    "content,words",
    [
        (b"\x00\xff garbage \x13" * 40, ["bad.stl"]),
        (b"", ["empty"]),
    ],
)
def test_cli_refuses_bad_files(tmp_path, content, words):
    bad = tmp_path / "bad.stl"
    bad.write_bytes(content)
    out = tmp_path / "out"
    _assert_refused(_cli(["make-tracks", str(bad), "--out", str(out)]), out, *words)


def test_cli_refuses_missing_file(tmp_path):
    out = tmp_path / "out"
    _assert_refused(
        _cli(["make-tracks", str(tmp_path / "nope.stl"), "--out", str(out)]),
        out,
        "nope.stl",
        "not found",
    )


def test_cli_takes_a_sphere_with_many_holes(tmp_path):
    """Faces at least 8 mm apart missing from a sphere: the level set closes the holes, and
    the report counts them (the old loader refused such a mesh as open)."""
    sphere = trimesh.creation.icosphere(3, 30.0)
    c = sphere.triangles_center
    gone = []
    for k in range(len(c)):
        if all(np.linalg.norm(c[k] - c[g]) > 8.0 for g in gone):
            gone.append(k)
    tri = sphere.triangles[gone]
    perimeter = np.linalg.norm(tri - tri[:, [1, 2, 0]], axis=2).sum(axis=1).max()
    sphere.update_faces(~np.isin(np.arange(len(c)), gone))
    path = tmp_path / "open.stl"
    sphere.export(path)
    out = tmp_path / "out"
    res = _cli(["make-tracks", str(path), "--out", str(out), "--faces", "1500"])
    assert res.exit_code == 0, res.output
    rep = json.loads((out / "report.json").read_text())
    surf = rep["artist_surface"]
    assert surf["holes"] == len(gone) > 40 and not surf["closed"]
    assert surf["largest_hole_perimeter_mm"] == pytest.approx(perimeter, rel=1e-6)
    assert f"{len(gone)} hole(s)" in res.output and "closed by the level set" in res.output
    reduced = load_stl(out / "reduced.stl")
    # a sphere of radius 30 (its icosphere facets are at 29.6-30 mm) reduced by 2 mm
    assert np.allclose(np.linalg.norm(reduced.vertices, axis=1), 27.8, atol=0.4)


def test_cli_refuses_two_bodies(tmp_path):
    a = trimesh.creation.box(extents=(40, 40, 20))
    b = trimesh.creation.box(extents=(40, 40, 20))
    b.apply_translation((100, 0, 0))
    path = tmp_path / "two.ply"
    trimesh.util.concatenate([a, b]).export(path)
    out = tmp_path / "out"
    _assert_refused(
        _cli(["make-tracks", str(path), "--out", str(out)]),
        out,
        "encloses 2 separate bodies",
        "do not touch",
        "join them",
    )


def test_cli_metres_need_unit(tmp_path):
    path = ellipsoid(tmp_path / "m.stl", radii=(0.04, 0.03, 0.02))
    out = tmp_path / "out"
    _assert_refused(
        _cli(["make-tracks", str(path), "--out", str(out)]),
        out,
        "m.stl: the mesh is only 0.08 mm across, so it is not in millimetres; "
        "give its unit (--unit m or --unit cm) or its size (--fit-mm)",
    )
    res = _cli(["make-tracks", str(path), "--out", str(out), "--unit", "m", "--faces", "1500"])
    assert res.exit_code == 0, res.output
    rep = json.loads((out / "report.json").read_text())
    assert rep["repairs"][0].startswith("scaled from m to mm")
    # each repair is also a progress line, except welding an STL's separate corners
    assert "make-tracks: scaled from m to mm (x1000)\n" in res.output
    merged = [r for r in rep["repairs"] if r.startswith("merged")]
    assert merged and "repaired: merged" not in res.output


def test_scene_artist_in_metres_is_refused(tmp_path):
    """Through a scene (whose unit defaults to mm) the metres check runs too."""
    ellipsoid(tmp_path / "m.stl", radii=(0.04, 0.03, 0.02))
    (tmp_path / "s.toml").write_text('[geometry]\nartist = "m.stl"\n')
    out = tmp_path / "out"
    _assert_refused(
        _cli(["run", str(tmp_path / "s.toml"), "--out", str(out)]),
        out,
        "m.stl: the mesh is only 0.08 mm across, so it is not in millimetres; "
        'set [geometry].unit = "m" (or "cm") or [geometry].fit_mm',
    )


def test_scene_names_in_errors(tmp_path):
    """With SCENE_NAMES (the scene's make-tracks stage) hints name scene keys, not flags."""
    small = ellipsoid(tmp_path / "m.stl", radii=(0.04, 0.03, 0.02))
    with pytest.raises(
        GeometryError,
        match=r'set \[geometry\]\.unit = "m" \(or "cm"\) or '
        r"\[geometry\]\.fit_mm$",
    ):
        make_tracks(small, tmp_path / "o", unit="mm", names=SCENE_NAMES)
    big = ellipsoid(tmp_path / "e.stl")
    with pytest.raises(
        GeometryError,
        match=r"consumes the whole body: it is at most 3[0-9.]+ "
        r"mm thick \(at \(.*\) mm\), thinner than twice "
        r"the cover; use a smaller \[tracks\]\.cover_mm$",
    ):
        make_tracks(big, tmp_path / "o", unit="mm", cover_mm=25.0, faces=1500, names=SCENE_NAMES)
    with pytest.raises(GeometryError, match=r"^\[tracks\]\.track_radius_mm: 7 mm"):
        make_tracks(big, tmp_path / "o", track_radius_mm=7.0, names=SCENE_NAMES)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "opts,words",
    [
        (
            ["--spacing-x-mm", "500", "--spacing-y-mm", "500", "--origin-mm", "250", "250"],
            ["misses the shape"],
        ),
        (["--track-radius-mm", "7"], ["--track-radius-mm", "half the grid spacing"]),
        (["--cover-mm", "25"], ["consumes", "--cover-mm"]),
        (["--split-z-mm", "40"], ["--split-z-mm", "outside"]),
    ],
)
def test_cli_refuses_bad_options(tmp_path, opts, words):
    path = ellipsoid(tmp_path / "e.stl")
    out = tmp_path / "out"
    _assert_refused(
        _cli(["make-tracks", str(path), "--out", str(out), "--faces", "1500", *opts]), out, *words
    )


def test_make_artist_cli(tmp_path):
    res = _cli(["make-artist", "--out", str(tmp_path / "a.obj")])
    assert res.exit_code == 0, res.output
    m = trimesh.load_mesh(tmp_path / "a.obj", process=True)
    assert m.is_watertight and len(m.faces) >= 100_000
    res = _cli(["make-artist", "--out", str(tmp_path / "a.xyz")])
    assert res.exit_code == 1 and "expected .stl, .obj or .ply" in res.output
    assert "(mm)" in _cli(["make-tracks", "--help"]).output


def _rounded_box(path):
    import manifold3d

    m = (
        manifold3d.Manifold.cube((80.0, 60.0, 30.0), True)
        .minkowski_sum(manifold3d.Manifold.sphere(6.0, 24))
        .to_mesh()
    )
    trimesh.Trimesh(np.asarray(m.vert_properties)[:, :3], m.tri_verts).export(path)


def _disc(path):
    trimesh.creation.cylinder(radius=50.0, height=10.0, sections=128).export(path)


def _lying_cylinder(path):
    cyl = trimesh.creation.cylinder(radius=20.0, height=100.0, sections=96)
    cyl.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
    cyl.export(path)


@pytest.mark.parametrize(
    "make,extents",
    [
        (_rounded_box, None),  # sliver faces broke curves into overlapping pieces: tunnels
        (_disc, None),  # tubes along the sharp rim cut off slivers: 9 bodies
        (_lying_cylinder, [96.0, 36.0, 36.0]),  # long side triangles: the offset came out wrong
    ],
)
def test_other_shapes_give_one_piece_without_tunnels(tmp_path, make, extents):
    art = tmp_path / "shape.stl"
    make(art)
    report = make_tracks(art, tmp_path / "out", faces=2000)
    assert report["genus"]["tunnels"] == 0
    assert report["genus"]["tracked_top"] == report["genus"]["reduced_top"] == 0
    piece = load_stl(tmp_path / "out" / "tracked_top.stl")
    assert piece.is_watertight and piece.is_volume
    assert len(piece.split(only_watertight=False)) == 1
    reduced = load_stl(tmp_path / "out" / "reduced.stl")
    tx = read_taxels(tmp_path / "out" / "taxels.csv")
    assert len(tx.ids) >= 10
    # brute force over all triangles: the reduced cylinder has long strips along its axis
    t = reduced.triangles
    d = [
        np.linalg.norm(
            closest_on_triangles(np.tile(p, (len(t), 1)), t[:, 0], t[:, 1], t[:, 2]) - p, axis=1
        ).min()
        for p in tx.xyz_mm
    ]
    assert max(d) <= ON_SURFACE_MM
    if extents is not None:
        assert np.allclose(reduced.extents, extents, atol=0.3)
        assert report["offset_error"]["reduced_to_ideal_mean_mm"] < 0.2  # was 1.4


def test_cli_repairs_inconsistent_winding(tmp_path):
    s = trimesh.creation.icosphere(3, 30.0)
    f = s.faces.copy()
    f[::2] = f[::2, ::-1]
    path = tmp_path / "flip.obj"
    trimesh.Trimesh(s.vertices, f, process=False).export(path)
    out = tmp_path / "out"
    res = _cli(["make-tracks", str(path), "--out", str(out), "--faces", "1500"])
    assert res.exit_code == 0, res.output
    rep = json.loads((out / "report.json").read_text())
    assert any("winding" in r for r in rep["repairs"])
    assert "make-tracks: repaired: made the face winding consistent and outward" in res.output


def test_tall_thin_column_gives_one_piece_quickly(tmp_path):
    # a capped column r = 8 mm, 150 mm tall: splitting its 150 mm side triangles made 283k
    # faces (27 s), and the sawtooth facets of the offset wall looked upward-facing, so
    # tracks ran down the wall and the piece reloaded as 2 bodies
    art = tmp_path / "col.stl"
    trimesh.creation.cylinder(radius=8.0, height=150.0, sections=64).export(art)
    out = tmp_path / "out"
    res = _cli(["make-tracks", str(art), "--out", str(out)])
    assert res.exit_code == 0, res.output
    rep = json.loads((out / "report.json").read_text())
    assert rep["split_long_triangles"] and rep["split_edge_mm"] < 2.5
    assert rep["triangles"]["split"] < 25_000
    assert rep["warnings"] == [] and rep["genus"]["tracked_top"] == 0
    piece = load_stl(out / "tracked_top.stl")
    assert piece.is_watertight and piece.is_volume
    assert len(piece.split(only_watertight=False)) == 1
    reduced = load_stl(out / "reduced.stl")
    assert np.allclose(reduced.extents, [12.0, 12.0, 146.0], atol=0.3)
    assert rep["offset_error"]["reduced_to_ideal_mean_mm"] < 0.1
    # the grid fits one x- and one y-line on the 12 mm top: one taxel at its centre, facing
    # up; the tracks stay on the top (they ran down to z = 1.8 mm)
    tx = read_taxels(out / "taxels.csv")
    assert len(tx.ids) == 1
    assert np.allclose(tx.xyz_mm, [[0.0, 0.0, 73.0]], atol=0.1)
    assert tx.normals[0, 2] > 0.99
    assert load_stl(out / "tracks.stl").bounds[0, 2] > 73.0 - 4.0


def test_cli_refuses_tracks_that_cut_the_piece_apart(tmp_path):
    import manifold3d

    # an arch whose bridge is 2 mm thick after the cover: 5.5 mm tubes cut it to pieces
    arch = manifold3d.Manifold.cube((100.0, 30.0, 60.0), True) - manifold3d.Manifold.cube(
        (80.0, 40.0, 54.0), True
    ).translate((0, 0, -6.0))
    m = arch.to_mesh()
    path = tmp_path / "arch.stl"
    trimesh.Trimesh(np.asarray(m.vert_properties)[:, :3], m.tri_verts).export(path)
    out = tmp_path / "out"
    res = _cli(
        [
            "make-tracks",
            str(path),
            "--out",
            str(out),
            "--faces",
            "1500",
            "--split-z-mm",
            "-10",
            "--track-radius-mm",
            "5.5",
        ]
    )
    _assert_refused(res, out, "arch.stl", "bodies", "--track-radius-mm", "--origin-mm")


def test_coarse_reduction_warns_when_it_departs_from_the_offset(tmp_path):
    """Too few --faces for the shape: the reduced surface departs from the ideal offset by
    more than half the cover, and make-tracks says so (report and progress)."""
    art = tmp_path / "ball.stl"
    trimesh.creation.icosphere(4, 40.0).export(art)
    out = tmp_path / "out"
    res = _cli(["make-tracks", str(art), "--out", str(out), "--faces", "150"])
    assert res.exit_code == 0, res.output
    rep = json.loads((out / "report.json").read_text())
    assert rep["offset_error"]["hausdorff_mm"] > 1.0
    warn = [w for w in rep["warnings"] if "departs from the ideal 2 mm offset" in w]
    assert warn and warn[0].endswith("raise --faces or lower --cover-mm")
    assert f"warning: {warn[0]}" in res.output


def test_a_body_touching_itself_along_an_edge_is_filled_closed():
    """Two blocks meeting only along the vertical edge x = y = 10 mm, joined by a slab on
    top: one shell, but a mesh file would reload that edge with four faces (as the
    Stanford bunny's offset does at its ear). A capsule fills it: closed, one body."""
    import manifold3d

    from fruitcli.geometry.mesh.export import weld_float32
    from fruitcli.geometry.tracks.reduce import _fill_pinched_edges, manifold_arrays

    block = manifold3d.Manifold.cube((10.0, 10.0, 10.0))
    slab = manifold3d.Manifold.cube((20.0, 20.0, 2.0)).translate((0.0, 0.0, 10.0))
    body = block + block.translate((10.0, 10.0, 0.0)) + slab
    assert len(body.decompose()) == 1
    before = trimesh.Trimesh(*weld_float32(*manifold_arrays(body)))
    assert not before.is_watertight

    radius = 0.5
    filled, where = _fill_pinched_edges(body, radius)
    after = trimesh.Trimesh(*weld_float32(*manifold_arrays(filled)))
    assert after.is_watertight and len(after.split(only_watertight=False)) == 1
    assert where == ["(10.0, 10.0, 5.0)"]
    # the filling adds at most a capsule's volume along the 10 mm edge (12-gon sphere)
    added = filled.volume() - body.volume()
    assert 0.0 < added <= np.pi * radius**2 * 10.0 + 4.0 / 3.0 * np.pi * radius**3
