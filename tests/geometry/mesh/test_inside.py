"""Any mesh with an inside: winding number closed forms, the loader's counts and formats,
and make-tracks end to end on the meshes artists have (tests/helpers/artist_meshes.py)."""

import json

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import GeometryError
from fruitcli.geometry.mesh import load, winding
from fruitcli.geometry.tracks.make_tracks import make_tracks
from tests.helpers.artist_meshes import (
    head_with_eye_sockets,
    machined_part,
    open_sheet,
    overlapping_figure,
    plane,
    sphere_with_holes,
    teapot_with_open_lid,
)


def _cli(args):
    return CliRunner().invoke(cli, args)


def _refused(result, out, *words):
    assert result.exit_code == 1, result.output
    line = result.output.strip().splitlines()[-1]
    assert line.startswith("Error:") and "Traceback" not in result.output
    for w in words:
        assert w in line, line
    assert not out.exists() or not any(out.iterdir())


def test_winding_number_of_a_sphere_with_a_hole_is_its_solid_angle():
    """w at the centre of a sphere missing a cap of half-angle t is the solid angle of the
    rest over 4 pi: 1 - (1 - cos t) / 2; outside it is 0, and two overlapping closed
    spheres give 2 where they overlap."""
    s = trimesh.creation.icosphere(6, 40.0)
    c = s.triangles_center / 40.0
    keep = c[:, 2] < np.cos(np.radians(40.0))
    holed = load.clean(np.asarray(s.vertices), np.asarray(s.faces)[keep])
    kept = trimesh.Trimesh(s.vertices, s.faces[keep], process=False)
    edges = kept.edges_sorted[trimesh.grouping.group_rows(kept.edges_sorted, require_count=1)]
    rim = kept.vertices[np.unique(edges)]
    t = np.arccos(np.mean(rim[:, 2]) / 40.0)  # the hole's actual rim
    wn = winding.Winding(holed.vertices, holed.faces)
    w = wn(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -200.0]]))
    assert w[0] == pytest.approx(1 - (1 - np.cos(t)) / 2, abs=0.01)
    # far away an open surface's w is minus the solid angle of its hole over 4 pi:
    # pi 25.7^2 / 200^2 / (4 pi) = 0.004 for this one
    assert abs(w[1]) < 0.006
    assert holed.holes == 1
    two = trimesh.util.concatenate(
        [
            trimesh.creation.icosphere(4, 10.0),
            trimesh.creation.icosphere(4, 10.0).apply_translation((10, 0, 0)),
        ]
    )
    w2 = winding.Winding(two.vertices, two.faces)(np.array([[5.0, 0, 0], [-5.0, 0, 0]]))
    assert np.allclose(w2, [2.0, 1.0], atol=5e-3)  # the fast (Barnes-Hut) evaluation


def test_grid_winding_interpolates_only_far_from_the_surface():
    s = sphere_with_holes()
    wn = winding.Winding(s.vertices, s.faces)
    axes = [np.arange(-45.0, 45.1, 3.0)] * 3
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    direct = wn(pts).reshape(len(axes[0]), len(axes[1]), len(axes[2]))
    r = np.abs(np.linalg.norm(pts, axis=1) - 40.0).reshape(direct.shape)
    near = r < 10.0
    w = winding.grid_winding(wn, axes, near)
    assert np.array_equal(w[near], direct[near])
    assert np.abs(w - direct).max() < 0.02


def test_faces_inside_a_union_do_not_bound_it():
    """Two overlapping boxes: the faces of each inside the other are not part of the
    union's boundary; all the others are."""
    a = trimesh.creation.box(extents=(20, 20, 20))
    b = trimesh.creation.box(extents=(20, 20, 20)).apply_translation((10, 5, 3))
    m = trimesh.util.concatenate([a.subdivide().subdivide(), b.subdivide().subdivide()])
    s = load.clean(np.asarray(m.vertices), np.asarray(m.faces))
    assert s.parts == 2 and s.holes == 0
    bound = winding.boundary_faces(winding.Winding(s.vertices, s.faces), s.vertices, s.faces)
    c = s.vertices[s.faces].mean(axis=1)
    in_a = (np.abs(c) < 10 - 1e-9).all(axis=1)
    in_b = (np.abs(c - (10, 5, 3)) < 10 - 1e-9).all(axis=1)
    assert np.array_equal(bound, ~(in_a | in_b))


def test_loader_counts_and_orients_without_changing_the_surface(tmp_path):
    m = head_with_eye_sockets()
    f = np.asarray(m.faces).copy()
    f[::5] = f[::5, ::-1]  # scrambled winding
    trimesh.Trimesh(m.vertices, f, process=False).export(tmp_path / "head.ply")
    s = load.load_mesh(tmp_path / "head.ply")
    assert (s.holes, s.parts, s.non_manifold_edges) == (4, 3, 0)
    # the same triangles (as sets of corners), each part wound outward (positive volume)
    assert np.array_equal(np.sort(np.sort(s.faces, 1), 0), np.sort(np.sort(f, 1), 0))
    assert any("consistent and outward" in r for r in s.repairs)
    tri = s.vertices[s.faces]
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    assert vol > 0
    # a socket cup alone has one hole: its (zig-zag) rim about a circle of radius 7 mm
    cup = trimesh.creation.icosphere(3, 7.0)
    cup.update_faces(cup.triangles_center[:, 1] < 0.0)
    holes, perimeter = load.hole_loops(np.asarray(cup.vertices), np.asarray(cup.faces))
    rim = cup.edges_sorted[trimesh.grouping.group_rows(cup.edges_sorted, require_count=1)]
    length = np.linalg.norm(cup.vertices[rim[:, 0]] - cup.vertices[rim[:, 1]], axis=1).sum()
    assert holes == 1 and perimeter == pytest.approx(length, rel=1e-9)
    assert 2 * np.pi * 7 * 0.95 < perimeter < 2 * np.pi * 7 * 1.25


@pytest.mark.parametrize("suffix", [".off", ".glb", ".gltf"])
def test_other_formats_and_scenes_are_read(tmp_path, suffix):
    a = trimesh.creation.box(extents=(20, 20, 20))
    b = trimesh.creation.icosphere(2, 8.0)
    path = tmp_path / f"m{suffix}"
    if suffix == ".off":
        a.export(path)
        v, f, notes = load.read_mesh_file(path)
        assert np.allclose(v, a.vertices) and np.array_equal(f, a.faces) and notes == []
        return
    scene = trimesh.Scene()
    scene.add_geometry(a, node_name="a")
    scene.add_geometry(
        b, node_name="b", transform=trimesh.transformations.translation_matrix((30.0, 0, 0))
    )
    scene.export(path)
    v, f, notes = load.read_mesh_file(path)
    assert len(f) == len(a.faces) + len(b.faces)
    assert notes == ["merged the 2 meshes of the file into one"]
    assert v[:, 0].max() == pytest.approx(38.0, abs=1e-4)  # the transform applied


@pytest.mark.parametrize(
    "text,words",
    [
        (
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n",
            ["no triangles", "3 points only"],
        ),
        ("OFF\n3 1 0\n0 0 0\n10 0 0\n0 10 0\n3 0 1 9\n", ["cannot read", "outside the range"]),
        ("v 0 0 0\nv 10 0 0\nv 0 10 0\nf 1 2 7\n", ["faces refer to missing vertices"]),
        ("v 0 0 nan\nv 10 0 0\nv 0 10 0\nf 1 2 3\n", ["NaN or infinite"]),
        ("v 0 0 0\nv 9000 0 0\nv 0 10 0\nf 1 2 3\n", ["9000 mm across", "5000 mm"]),
    ],
)
def test_cli_refuses_what_is_not_a_mesh(tmp_path, text, words):
    name = (
        "bad.ply" if text.startswith("ply") else "bad.off" if text.startswith("OFF") else "bad.obj"
    )
    (tmp_path / name).write_text(text)
    out = tmp_path / "out"
    _refused(_cli(["make-tracks", str(tmp_path / name), "--out", str(out)]), out, name, *words)


def test_fit_mm_scales_after_the_unit(tmp_path):
    """A head 2.7 units across, fitted to 150 mm: the reduced body spans 150 - 2 x 2 mm."""
    m = trimesh.creation.icosphere(4, 1.0).apply_scale((1.35, 1.0, 1.1))
    m.export(tmp_path / "head.obj")
    out = tmp_path / "out"
    res = _cli(
        [
            "make-tracks",
            str(tmp_path / "head.obj"),
            "--out",
            str(out),
            "--fit-mm",
            "150",
            "--faces",
            "1500",
        ]
    )
    assert res.exit_code == 0, res.output
    rep = json.loads((out / "report.json").read_text())
    assert rep["fit_mm"] == 150.0
    assert "so that its largest extent is 150 mm (from 2.7 mm)" in res.output
    red = trimesh.load_mesh(out / "reduced.stl")
    assert red.extents.max() == pytest.approx(146.0, abs=0.4)
    _refused(
        _cli(
            [
                "make-tracks",
                str(tmp_path / "head.obj"),
                "--out",
                str(tmp_path / "o2"),
                "--fit-mm",
                "-3",
            ]
        ),
        tmp_path / "o2",
        "--fit-mm",
        "expected a size > 0",
    )


@pytest.mark.parametrize(
    "make,holes,parts",
    [
        (sphere_with_holes, 3, 1),
        (head_with_eye_sockets, 4, 3),
        (overlapping_figure, 0, 9),
        (teapot_with_open_lid, 2, 4),
    ],
)
def test_meshes_with_an_inside_give_tracks(tmp_path, make, holes, parts):
    path = tmp_path / "art.stl"
    make().export(path)
    rep = make_tracks(path, tmp_path / "out", faces=2000)
    s = rep["artist_surface"]
    assert (s["holes"], s["parts"]) == (holes, parts) and not s["closed"]
    assert s["parts_merged"] == (parts if parts > 1 else 0)
    assert s["winding_number_min"] > -0.2
    # overlapping parts add up: w reaches about 2 where two overlap
    assert s["winding_number_max"] == pytest.approx(2.0 if parts > 1 else 1.0, abs=0.45)
    assert (s["faces_dropped_inside_or_outside"] > 0) == (parts > 1)
    assert rep["taxels"] >= 1
    for name in ("reduced.stl", "tracked_top.stl"):
        back = trimesh.load_mesh(tmp_path / "out" / name)
        assert back.is_watertight and back.is_volume
        assert len(back.split(only_watertight=False)) == 1
    assert json.loads((tmp_path / "out" / "report.json").read_text())["artist_surface"] == s


def test_sphere_with_holes_is_offset_as_the_closed_sphere(tmp_path):
    """The caps closing the holes count as surface: the reduced body is the sphere of
    radius 40 - 2 mm, its holes included, and the offset error stays small."""
    path = tmp_path / "art.stl"
    sphere_with_holes().export(path)
    rep = make_tracks(path, tmp_path / "out", faces=3000)
    red = trimesh.load_mesh(tmp_path / "out" / "reduced.stl")
    r = np.linalg.norm(red.vertices, axis=1)
    # the caps are flatter than the sphere (w = 1/2 spans a hole nearly as a plane)
    c = red.vertices / r[:, None]
    axis3 = np.array([0, 1, 0.3]) / np.linalg.norm([0, 1, 0.3])
    on_sphere = (
        (-c[:, 2] < np.cos(np.radians(40)))
        & (c[:, 0] < np.cos(np.radians(30)))
        & (c @ axis3 < np.cos(np.radians(20)))
    )
    assert np.allclose(r[on_sphere], 38.0, atol=0.35)
    assert r.max() < 38.4
    assert rep["offset_error"]["hausdorff_mm"] < 1.0


@pytest.mark.parametrize(
    "make,words",
    [
        (open_sheet, ["no inside", "winding number reaches only 0.", "open sheet"]),
        (plane, ["no inside", "open sheet or a plane"]),
    ],
)
def test_cli_refuses_what_has_no_inside(tmp_path, make, words):
    path = tmp_path / "sheet.stl"
    make().export(path)
    out = tmp_path / "out"
    _refused(_cli(["make-tracks", str(path), "--out", str(out)]), out, "sheet.stl", *words)


def test_sharp_edged_part_gives_tracks_and_names_its_thin_wall(tmp_path):
    """The machined part 50 x 25 x 14 mm: tracks, and the 3 mm wall between the hole at
    x = 19 mm and the end x = 25 mm (thinner than twice the 2 mm cover) or the 4 mm one at
    the other end is named."""
    path = tmp_path / "part.stl"
    machined_part().export(path)
    rep = make_tracks(path, tmp_path / "out", faces=2000)
    assert rep["taxels"] >= 4 and rep["artist_surface"]["closed"]
    back = trimesh.load_mesh(tmp_path / "out" / "tracked_top.stl")
    assert back.is_watertight and len(back.split(only_watertight=False)) == 1
    w = [x for x in rep["warnings"] if "thinner than twice the cover" in x]
    assert w
    x, y, z = rep["offset_error"]["worst_at_mm"]
    assert 19.0 <= abs(x) <= 25.0  # the same 4 mm wall at the hole at x = -18 mm
    with pytest.raises(
        GeometryError,
        match=r"consumes the whole body: it is at most 1[0-9.]+ "
        r"mm thick \(at \(.*\) mm\)",
    ):
        make_tracks(path, tmp_path / "o2", cover_mm=7.5, faces=2000)


def test_scene_fit_mm_is_named_in_errors(tmp_path):
    from fruitcli.geometry.tracks.make_tracks import SCENE_NAMES
    from fruitcli.scene import load_scene

    trimesh.creation.icosphere(3, 0.5).export(tmp_path / "head.stl")  # 1 mm across
    (tmp_path / "s.toml").write_text('[geometry]\nartist = "head.stl"\nfit_mm = 120\n')
    assert load_scene(tmp_path / "s.toml").geometry.fit_mm == 120
    with pytest.raises(GeometryError, match=r"^\[geometry\]\.fit_mm: expected a size > 0"):
        make_tracks(tmp_path / "head.stl", tmp_path / "o", fit_mm=-1.0, names=SCENE_NAMES)
    with pytest.raises(
        GeometryError,
        match=r'set \[geometry\]\.unit = "m" \(or "cm"\) or '
        r"\[geometry\]\.fit_mm$",
    ):
        make_tracks(tmp_path / "head.stl", tmp_path / "o", names=SCENE_NAMES)
    assert not (tmp_path / "o").exists()
