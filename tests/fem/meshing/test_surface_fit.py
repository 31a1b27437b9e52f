"""Points on a curved body lie outside its straight-sided tet mesh by up to the chord's
sag; only points beyond the mesh's own fit to the surface are off the body."""

from __future__ import annotations

import numpy as np
import pytest

from fruitcli.fem.elements.barycentric import locate
from fruitcli.fem.meshing import surface_fit

OCTAHEDRON = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0]])
OCTA_FACES = np.array(
    [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
)
OCTA_TETS = np.array(  # the octahedron of radius 1 as 4 tets around the z axis (node 6: 0)
    [[0, 2, 4, 6], [2, 1, 4, 6], [1, 3, 4, 6], [3, 0, 4, 6]]
    + [[2, 0, 5, 6], [1, 2, 5, 6], [3, 1, 5, 6], [0, 3, 5, 6]]
)


def test_deviation_of_a_sphere_from_its_inscribed_octahedron_is_the_face_sag():
    """A unit sphere (its points along the 8 face normals among them) meshed by the
    octahedron through its 6 axis points: the farthest sphere point lies over a face
    centre, 1 - 1/sqrt(3) from the face's plane."""
    rng = np.random.default_rng(1)
    dirs = np.vstack(
        [rng.normal(size=(500, 3)), np.array(np.meshgrid(*[[-1, 1]] * 3)).T.reshape(-1, 3)]
    )
    sphere = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    dev = surface_fit.deviation_mm(sphere, np.zeros((0, 3), int), OCTAHEDRON, OCTA_FACES)
    assert dev == pytest.approx(1 - 1 / np.sqrt(3), rel=1e-9)
    assert surface_fit.deviation_mm(OCTAHEDRON, OCTA_FACES, OCTAHEDRON, OCTA_FACES) < 1e-12


def test_outside_distance_is_zero_inside_and_the_plane_distance_outside():
    nodes = np.vstack([OCTAHEDRON, [0.0, 0.0, 0.0]])
    normal = np.ones(3) / np.sqrt(3)  # of the face (0, 2, 4), at 1/sqrt(3) from 0
    points = np.array([[0.1, 0.1, 0.1], normal * (1 / np.sqrt(3) + 0.25), [0.0, 0.0, 1.5]])
    _, _, outside = locate(nodes, OCTA_TETS, points)
    got = surface_fit.outside_mm(nodes, OCTA_FACES, points, outside)
    assert got == pytest.approx([0.0, 0.25, 0.5], abs=1e-12)
    assert surface_fit.tolerance_mm(1.0, 5.0) == pytest.approx(1.1 + 0.005)
