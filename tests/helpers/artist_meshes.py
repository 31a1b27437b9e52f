"""Meshes of the kinds artists and labs bring, built in code (mm): holes, several
overlapping parts, an unclosed lid, an open sheet, a plane, a sharp-edged machined part."""

import numpy as np
import trimesh


def _drop(mesh, keep):
    m = trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=False)
    m.remove_unreferenced_vertices()
    return m


def sphere_with_holes(radius=40.0):
    """A sphere with three round holes (cap half-angles 10, 18 and 28 degrees)."""
    s = trimesh.creation.icosphere(5, radius)
    c = s.triangles_center / radius
    keep = np.ones(len(s.faces), bool)
    for axis, ang in (((0, 0, -1), 28), ((1, 0, 0), 18), ((0, 1, 0.3), 10)):
        a = np.asarray(axis, float) / np.linalg.norm(axis)
        keep &= c @ a < np.cos(np.radians(ang))
    return _drop(s, keep)


def head_with_eye_sockets():
    """An egg-shaped head 100 x 80 x 120 mm with two open eye holes, each with a socket
    cup modelled separately behind it (a gap between cup and hole)."""
    s = trimesh.creation.icosphere(5, 1.0)
    s.apply_scale((40.0, 50.0, 60.0))
    c = s.triangles_center
    keep = np.ones(len(s.faces), bool)
    eyes = [np.array([x, 44.0, 12.0]) for x in (-16.0, 16.0)]
    for e in eyes:
        keep &= np.linalg.norm(c - e, axis=1) > 9.0
    parts = [_drop(s, keep)]
    for e in eyes:
        cup = trimesh.creation.icosphere(3, 7.0)
        cup = _drop(cup, cup.triangles_center[:, 1] < 0.0)  # back half: the socket
        cup.invert()  # seen from the front
        cup.apply_translation(e - (0, 2.0, 0))
        parts.append(cup)
    return trimesh.util.concatenate(parts)


def overlapping_figure():
    """A figure of nine overlapping closed parts (torso, head, neck, arms, legs, feet)."""
    parts = []
    for c, r in (
        ((0, 0, 0), (18, 12, 28)),
        ((0, 0, 40), (11, 11, 11)),
        ((0, 0, 29), (5, 5, 6)),
        ((-24, 0, 8), (16, 6, 6)),
        ((24, 0, 8), (16, 6, 6)),
        ((-9, 0, -38), (7, 7, 18)),
        ((9, 0, -38), (7, 7, 18)),
        ((-9, 6, -56), (6, 10, 4)),
        ((9, 6, -56), (6, 10, 4)),
    ):
        e = trimesh.creation.icosphere(4, 1.0)
        e.apply_scale(r)
        e.apply_translation(c)
        parts.append(e)
    return trimesh.util.concatenate(parts)


def teapot_with_open_lid():
    """A teapot-like body open at the top, a lid resting above the opening without
    closing it, a spout and a handle overlapping the body."""
    body = trimesh.creation.icosphere(5, 1.0)
    body.apply_scale((50.0, 50.0, 38.0))
    body = _drop(body, body.triangles_center[:, 2] < 30.0)
    lid = trimesh.creation.icosphere(4, 1.0)
    lid.apply_scale((22.0, 22.0, 10.0))
    lid = _drop(lid, lid.triangles_center[:, 2] > 0.0)
    lid.apply_translation((0, 0, 27.0))
    spout = trimesh.creation.cylinder(radius=6.0, height=40.0, sections=32)
    spout.apply_transform(trimesh.transformations.rotation_matrix(np.radians(60), (0, 1, 0)))
    spout.apply_translation((55.0, 0, 10.0))
    handle = trimesh.creation.torus(major_radius=16.0, minor_radius=4.0)
    handle.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (1, 0, 0)))
    handle.apply_translation((-52.0, 0, 5.0))
    return trimesh.util.concatenate([body, lid, spout, handle])


def open_sheet():
    """A single open sheet: a wavy 80 x 60 mm surface."""
    x, y = np.meshgrid(np.linspace(-40, 40, 41), np.linspace(-30, 30, 31), indexing="ij")
    z = 5.0 * np.sin(x / 12.0) * np.cos(y / 15.0)
    v = np.c_[x.ravel(), y.ravel(), z.ravel()]
    i, j = np.meshgrid(np.arange(40), np.arange(30), indexing="ij")
    a = (i * 31 + j).ravel()
    f = np.r_[np.c_[a, a + 31, a + 32], np.c_[a, a + 32, a + 1]]
    return trimesh.Trimesh(v, f, process=False)


def plane():
    """A flat 100 x 100 mm square, two triangles."""
    v = np.array([[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]], float)
    return trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)


def machined_part():
    """A sharp-edged part 50 x 25 x 14 mm: a block with a pocket, two through holes and a
    chamfer-free step, as a CAD export (few long triangles)."""
    import manifold3d as mf

    block = mf.Manifold.cube((50.0, 25.0, 14.0), True)
    step = mf.Manifold.cube((14.0, 27.0, 6.0), True).translate((-18.0, 0, 5.0))
    pocket = mf.Manifold.cube((16.0, 12.0, 8.0), True).translate((6.0, 0, 5.0))
    holes = [
        mf.Manifold.cylinder(20.0, 3.0, 3.0, 48, True).translate((x, 0, 0)) for x in (-18.0, 19.0)
    ]
    part = mf.Manifold.batch_boolean([block, step, pocket, *holes], mf.OpType.Subtract)
    m = part.to_mesh()
    return trimesh.Trimesh(np.asarray(m.vert_properties)[:, :3], np.asarray(m.tri_verts))


ALL = {
    "sphere_with_holes": sphere_with_holes,
    "head_with_eye_sockets": head_with_eye_sockets,
    "overlapping_figure": overlapping_figure,
    "teapot_with_open_lid": teapot_with_open_lid,
    "open_sheet": open_sheet,
    "plane": plane,
    "machined_part": machined_part,
}
