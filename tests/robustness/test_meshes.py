"""Meshes a scan or a modeller gives: isolated triangles, a single triangle, a body far
from the origin. Tracked, or refused in one line naming the file."""

import numpy as np
from click.testing import CliRunner

from fruitcli.cli.main import cli


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def sphere_with(extra_vertices=None, shift=(0.0, 0.0, 0.0)):
    import trimesh

    ball = trimesh.creation.icosphere(3, radius=40.0)
    verts, faces = ball.vertices + np.asarray(shift), ball.faces
    if extra_vertices is not None:
        faces = np.r_[faces, [[len(verts), len(verts) + 1, len(verts) + 2]]]
        verts = np.r_[verts, extra_vertices]
    return trimesh.Trimesh(verts, faces, process=False)


def test_orient_faces_takes_isolated_faces():
    from fruitcli.geometry.mesh.load import orient_faces

    faces = np.array([[0, 1, 2], [1, 2, 3], [4, 5, 6]])  # 1-2 run the same way
    out, conflicts = orient_faces(faces)
    assert conflicts == 0
    assert out.tolist() == [[0, 1, 2], [3, 2, 1], [4, 5, 6]]
    out, conflicts = orient_faces(np.array([[0, 1, 2]]))
    assert out.tolist() == [[0, 1, 2]] and conflicts == 0


def test_a_closed_body_with_an_isolated_triangle_is_tracked(tmp_path):
    path = tmp_path / "iso.stl"
    sphere_with([[100, 100, 100], [101, 100, 100], [100, 101, 100]]).export(path)
    res = run("make-tracks", path, "--out", tmp_path / "o")
    assert res.exit_code == 0, res.output
    taxels = (tmp_path / "o" / "taxels.csv").read_text().splitlines()
    assert len([t for t in taxels if t and not t.startswith("#")]) > 10


def test_a_one_triangle_mesh_is_one_line(tmp_path):
    import trimesh

    path = tmp_path / "one.stl"
    trimesh.Trimesh([[0, 0, 0], [10, 0, 0], [0, 10, 0]], [[0, 1, 2]], process=False).export(path)
    res = run("make-tracks", path, "--out", tmp_path / "o")
    assert res.exit_code == 1 and "Traceback" not in res.output
    assert res.output.strip().splitlines()[-1].startswith(f"Error: {path}: the mesh has no inside")
    assert not (tmp_path / "o").exists()


def test_a_body_far_from_the_origin_is_one_line(tmp_path):
    path = tmp_path / "far.stl"
    sphere_with(shift=(1e9, 0.0, 0.0)).export(path)
    res = run("make-tracks", path, "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert res.output.strip().splitlines()[-1] == (
        f"Error: {path}: the mesh lies up to 1e+09 mm from the origin, more than 5000 mm; "
        "move it near the origin (the outputs are in the mesh's own coordinates)"
    )


def test_a_thin_closed_plate_is_not_called_an_open_sheet(tmp_path):
    import trimesh

    path = tmp_path / "plate.stl"
    trimesh.creation.box(extents=(200.0, 200.0, 2.0)).export(path)
    res = run("make-tracks", path, "--out", tmp_path / "o", "--cover-mm", "0.5")
    assert res.exit_code == 1
    line = res.output.strip().splitlines()[-1]
    assert line.startswith(f"Error: {path}: the mesh has no inside")
    assert "or a closed body thinner than about" in line and "--faces" in line


def test_a_garbage_text_mesh_is_one_line(tmp_path):
    from fruitcli.errors import GeometryError
    from fruitcli.geometry.mesh.load import load_mesh

    path = tmp_path / "chamber.obj"
    path.write_bytes(np.random.default_rng(3).bytes(4000))
    try:
        load_mesh(path)
    except GeometryError as exc:
        assert str(exc).startswith(f"{path}: ") and "\n" not in str(exc)
    else:
        raise AssertionError("garbage read as a mesh")
