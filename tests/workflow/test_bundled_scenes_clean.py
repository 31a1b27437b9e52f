"""The bundled scenes' taxels and yarn tracks lie on their bodies: simulate's check
(`fem.stage._off_body`, on the mesh tetra writes) finds none off the surface, and a
taxel moved 2 mm out along its normal is found."""

from __future__ import annotations

import numpy as np
import pytest

from fruitcli import bundled
from fruitcli.fem import io
from fruitcli.fem.elements.barycentric import locate
from fruitcli.fem.stage import _off_body
from fruitcli.fem.yarn import read_tracks
from fruitcli.scene import load_scene
from fruitcli.tables import read_taxels
from fruitcli.workflow import planner


def _off(out, points):
    mesh = io.load_mesh(out / "tetra" / "mesh.npz")
    _, _, outside = locate(mesh["nodes"], mesh["tets"], points)
    return _off_body(mesh)(points, outside)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "source"), [("fruit-deformed", "make-tracks"), ("touchpad-4x4", "pad-grid")]
)
def test_bundled_taxels_and_tracks_lie_on_the_body(tmp_path, name, source):
    scene = load_scene(bundled.export_scene(name, tmp_path / "scenes"))
    out = tmp_path / name
    planner.run(scene, out, until="tetra")
    table = read_taxels(out / source / "taxels.csv")
    points = np.concatenate([t.points for t in read_tracks(out / source / "tracks.csv")])
    assert not _off(out, table.xyz_mm).any()
    assert not _off(out, points).any()
    # the pad's taxels lie on its top face (z = thickness); the Fruit's file has normals
    normal = table.normals[0] if table.normals is not None else np.array([0.0, 0.0, 1.0])
    assert _off(out, table.xyz_mm[:1] + 2.0 * normal)[0] > 0.5


def test_fruit_breathing_meshes_what_fruit_deformed_meshes(tmp_path):
    """fruit-breathing's taxels, tracks and mesh have the hashes of fruit-deformed's (the
    test above covers both)."""
    hashes = []
    for name in ("fruit-deformed", "fruit-breathing"):
        scene = load_scene(bundled.export_scene(name, tmp_path / "scenes"))
        steps = planner.plan(scene, tmp_path / name, until="tetra")
        hashes.append({s.stage: s.hash for s in steps})
    assert hashes[0] == hashes[1] and hashes[0]["tetra"]
