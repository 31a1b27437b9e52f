"""make-mold: closed printable parts that do not overlap, a cavity equal to the piece (less
the pour and vent channels), ridges where the tracks are, mold.json, and bad options (one
line, nothing written)."""

import json
from itertools import combinations

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.geometry.mesh.distance import SurfaceDistance
from fruitcli.geometry.mesh.winding import Winding
from fruitcli.geometry.tracks.reduce import to_manifold64

SCENE = """[geometry]
artist = "ell.stl"
[[geometry.chamber]]
name = "c1"
ellipsoid = { center_mm = [0, 0, 7], radii_mm = [12, 8, 3.5] }
[[geometry.chamber]]
name = "c2"
ellipsoid = { center_mm = [-18, 0, 0], radii_mm = [6, 6, 3] }
[tracks]
faces = 2000
"""


@pytest.fixture(scope="module")
def molded(tmp_path_factory):
    d = tmp_path_factory.mktemp("mold")
    m = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    m.apply_scale((40, 30, 20))
    m.export(d / "ell.stl")
    (d / "s.toml").write_text(SCENE)
    res = CliRunner().invoke(cli, ["make-mold", str(d / "s.toml"), "--out", str(d / "out")])
    assert res.exit_code == 0, res.output
    return d / "out", json.loads((d / "out" / "mold.json").read_text()), res.output


def _solid(path):
    m = trimesh.load_mesh(path, process=True)
    return m, to_manifold64(np.asarray(m.vertices), np.asarray(m.faces))


def test_every_part_is_a_closed_manifold(molded):
    import manifold3d as mf

    out, rep, _ = molded
    names = [p for m in rep["molds"] for p in m["parts"]]
    assert sorted(names) == sorted(p.name for p in out.glob("*.stl"))
    assert [m["piece"] for m in rep["molds"]] == ["top", "bottom"]
    # c1 lies in the top piece, c2 straddles the split plane z = 0: a core in each half
    assert rep["molds"][0]["cores"] == ["c1", "c2"] and rep["molds"][1]["cores"] == ["c2"]
    for name in names:
        mesh, solid = _solid(out / name)
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0, name
        assert len(mesh.split(only_watertight=False)) == 1, name
        assert solid.status() == mf.Error.NoError
        vol = [m["part_volumes_mm3"][name] for m in rep["molds"] if name in m["parts"]][0]
        assert mesh.volume == pytest.approx(vol, rel=1e-3)


def test_parts_do_not_overlap_and_enclose_the_piece(molded):
    import manifold3d as mf

    out, rep, _ = molded
    tracks = out / "make-tracks"
    top = _solid(tracks / "tracked_top.stl")[1]
    z0 = rep["molds"][0]["parting_plane_z_mm"]
    bottom = _solid(tracks / "reduced.stl")[1].trim_by_plane((0, 0, -1.0), -z0)
    for m, piece in zip(rep["molds"], (top, bottom), strict=True):
        parts = {p: _solid(out / p)[1] for p in m["parts"]}
        for (a, pa), (b, pb) in combinations(parts.items(), 2):
            assert (pa ^ pb).volume() < 1e-6 * min(pa.volume(), pb.volume()), (a, b)
        b = m["box_mm"]
        outer = mf.Manifold.cube(tuple(np.subtract(b[3:], b[:3]))).translate(tuple(b[:3]))
        # the pour hole and vents: vertical channels from the given points to the box top
        channels = [
            mf.Manifold.cylinder(b[5] + 1 - (z - 0.5), d / 2, d / 2, 48).translate((x, y, z - 0.5))
            for (x, y, z), d in [(m["pour_hole_mm"], m["pour_diameter_mm"])]
            + [(v, m["vent_diameter_mm"]) for v in m["vents_mm"]]
        ]
        cavity = mf.Manifold.batch_boolean([outer, *parts.values(), *channels], mf.OpType.Subtract)
        cores = [p for n, p in parts.items() if "_core_" in n]
        silicone = mf.Manifold.batch_boolean([piece, *cores], mf.OpType.Subtract)
        differ = (cavity - silicone).volume() + (silicone - cavity).volume()
        assert differ < 0.01 * silicone.volume(), m["piece"]
        assert m["piece_volume_mm3"] == pytest.approx(silicone.volume(), rel=2e-3)
        assert m["silicone_ml"] == pytest.approx(m["piece_volume_mm3"] / 1000, abs=0.01)
        assert m["silicone_g"] == pytest.approx(m["silicone_ml"] * 1.07, abs=0.1)
        assert m["undercut_area_mm2"][f"{m['piece']}_plate.stl"] == 0.0


def test_ridges_of_the_top_shell_reproduce_the_tracks(molded):
    """Track centre points, moved half a track radius into the body, lie inside the top
    shell (its ridges fill the grooves); moved a radius and a half in, they lie in the
    cavity (the piece's silicone), not in the shell. (The pour hole and vents keep off the
    tracks, so that no channel cuts a ridge.)"""
    from fruitcli.tables import read_table

    out, rep, _ = molded
    tracks = out / "make-tracks"
    t = read_table(tracks / "tracks.csv", ["track", "point", "x_mm", "y_mm", "z_mm"])
    last = np.r_[t["track"][1:] != t["track"][:-1], True]
    inner = (t["point"] > 0) & ~last  # a tube ends in a flat cap at its ends
    p = np.c_[t["x_mm"], t["y_mm"], t["z_mm"]][inner][::7]
    red = trimesh.load_mesh(tracks / "reduced.stl", process=True)
    _, _, face = SurfaceDistance(red.vertices, red.faces).closest(p)
    n = red.face_normals[face]
    r = json.loads((tracks / "report.json").read_text())["track_radius_mm"]
    shell = trimesh.load_mesh(out / "top_shell.stl", process=True)
    wn = Winding(np.asarray(shell.vertices), np.asarray(shell.faces))
    z0 = rep["molds"][0]["parting_plane_z_mm"]
    keep = p[:, 2] > z0 + 2.5 * r  # tracks stay clear of the plane
    assert keep.sum() > 50
    assert (wn(p[keep] - 0.5 * r * n[keep]) > 0.5).all()
    assert (wn(p[keep] - 1.5 * r * n[keep]) < 0.5).all()


@pytest.mark.parametrize(
    "opts,words",
    [
        (["--wall-mm", "0.5"], ["--wall-mm", "at least 1 mm", "0.5 mm"]),
        (["--clearance-mm", "5"], ["--clearance-mm", "up to the wall (4 mm)", "5 mm"]),
        (["--key-radius-mm", "6"], ["--key-radius-mm", "smaller than the wall"]),
    ],
)
def test_cli_refuses_bad_mold_options(tmp_path, opts, words):
    trimesh.creation.icosphere(3, 30.0).export(tmp_path / "ell.stl")
    (tmp_path / "s.toml").write_text(SCENE)
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["make-mold", str(tmp_path / "s.toml"), "--out", str(out), *opts])
    assert res.exit_code == 1, res.output
    line = res.output.strip().splitlines()[-1]
    assert line.startswith("Error:") and "Traceback" not in res.output
    for w in words:
        assert w in line, line
    assert not out.exists()  # refused before make-tracks ran


def test_scene_mold_options_are_named_in_errors(tmp_path):
    trimesh.creation.icosphere(3, 30.0).export(tmp_path / "ell.stl")
    (tmp_path / "s.toml").write_text(SCENE + "[mold]\nwall_mm = 0.8\n")
    res = CliRunner().invoke(
        cli, ["make-mold", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]
    )
    assert res.exit_code == 1
    assert "Error: [mold].wall_mm: expected a wall of at least 1 mm, got 0.8 mm" in res.output
