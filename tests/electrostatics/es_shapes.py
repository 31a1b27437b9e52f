"""Small gmsh models with closed-form capacitances, for the field solver's tests (mm)."""

from __future__ import annotations

import numpy as np

from fruitcli.electrostatics import occ_mesh


def _sizes(gmsh, fine: float, coarse: float, near: list, reach: float) -> None:
    """Element size `fine` on the surfaces `near` (dimTags), growing to `coarse` over
    `reach` mm."""
    field = gmsh.model.mesh.field
    d = field.add("Distance")
    field.setNumbers(d, "SurfacesList", [t for _, t in near])
    th = field.add("Threshold")
    field.setNumber(th, "InField", d)
    for key, val in (("SizeMin", fine), ("SizeMax", coarse), ("DistMin", 0.0), ("DistMax", reach)):
        field.setNumber(th, key, val)
    field.setAsBackgroundMesh(th)
    for key in ("MeshSizeFromPoints", "MeshSizeFromCurvature", "MeshSizeExtendFromBoundary"):
        gmsh.option.setNumber(f"Mesh.{key}", 0)


def _mesh(build, order: int) -> occ_mesh.TetMesh:
    gmsh = occ_mesh.start()
    try:
        build(gmsh)
        return occ_mesh.mesh_model(gmsh, order)
    finally:
        gmsh.finalize()


def _faces_where(gmsh, dim_tags, test) -> list[int]:
    """Boundary surfaces of `dim_tags` whose centre of mass passes `test(x, y, z)`."""
    out = []
    for _, s in gmsh.model.getBoundary(dim_tags, oriented=False):
        if test(*gmsh.model.occ.getCenterOfMass(2, abs(s))):
            out.append(abs(s))
    return out


def layered_plates(
    size_mm: float, layers_mm: list[float], h: float, order: int = 1
) -> occ_mesh.TetMesh:
    """A square capacitor of side `size_mm`: dielectric layers stacked from z = 0 (regions
    layer0, layer1, ...), plates `bottom` (z = 0) and `top`; the sides insulating, which
    is exact for the uniform field (a periodic cell)."""

    def build(gmsh):
        occ = gmsh.model.occ
        z, boxes = 0.0, []
        for t in layers_mm:
            boxes.append((3, occ.addBox(0, 0, z, size_mm, size_mm, t)))
            z += t
        out, _ = occ.fragment(boxes[:1], boxes[1:]) if len(boxes) > 1 else (boxes, None)
        occ.synchronize()
        vols = sorted(out, key=lambda d: occ.getCenterOfMass(3, d[1])[2])
        for k, v in enumerate(vols):
            gmsh.model.addPhysicalGroup(3, [v[1]], name=f"layer{k}")
        gmsh.model.addPhysicalGroup(
            2, _faces_where(gmsh, vols, lambda x, y, zz: abs(zz) < 1e-9), name="bottom"
        )
        gmsh.model.addPhysicalGroup(
            2, _faces_where(gmsh, vols, lambda x, y, zz: abs(zz - z) < 1e-9), name="top"
        )
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)

    return _mesh(build, order)


def two_cylinders(
    radius_mm: float,
    distance_mm: float,
    half_width_mm: float,
    length_mm: float,
    fine: float,
    coarse: float,
    order: int = 2,
) -> occ_mesh.TetMesh:
    """Two parallel cylinders along y (surfaces `left`, `right`), axes at x = -+D/2, z = 0,
    in a slab [-L, L] x [0, length] x [-L, L] of air; every slab face insulating (the y
    faces: the cylinders are infinitely long)."""

    def build(gmsh):
        occ = gmsh.model.occ
        box = occ.addBox(
            -half_width_mm, 0, -half_width_mm, 2 * half_width_mm, length_mm, 2 * half_width_mm
        )
        cyl = [
            occ.addCylinder(s * distance_mm / 2, 0, 0, 0, length_mm, 0, radius_mm) for s in (-1, 1)
        ]
        air, _ = occ.cut([(3, box)], [(3, c) for c in cyl])
        occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [air[0][1]], name="air")
        near = []
        for name, sign in (("left", -1), ("right", 1)):
            faces = _faces_where(
                gmsh,
                air,
                lambda x, y, z, s=sign: abs(x - s * distance_mm / 2) < 1e-6 and abs(z) < 1e-6,
            )
            gmsh.model.addPhysicalGroup(2, faces, name=name)
            near += [(2, f) for f in faces]
        _sizes(gmsh, fine, coarse, near, half_width_mm)

    return _mesh(build, order)


def sphere_over_plane(
    radius_mm: float, height_mm: float, domain_mm: float, fine: float, coarse: float, order: int = 2
) -> occ_mesh.TetMesh:
    """A sphere (surface `sphere`), centre at `height_mm` above the plane z = 0 (surface
    `plane`), in a half-ball of air of radius `domain_mm` (its curved face insulating)."""

    def build(gmsh):
        occ = gmsh.model.occ
        ball = occ.addSphere(0, 0, 0, domain_mm)
        cutter = occ.addBox(
            -domain_mm, -domain_mm, -domain_mm, 2 * domain_mm, 2 * domain_mm, domain_mm
        )
        half, _ = occ.cut([(3, ball)], [(3, cutter)])
        sph = occ.addSphere(0, 0, height_mm, radius_mm)
        air, _ = occ.cut(half, [(3, sph)])
        occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [air[0][1]], name="air")
        plane = _faces_where(gmsh, air, lambda x, y, z: abs(z) < 1e-6)
        small = _faces_where(gmsh, air, lambda x, y, z: abs(z - height_mm) < radius_mm)
        gmsh.model.addPhysicalGroup(2, plane, name="plane")
        gmsh.model.addPhysicalGroup(2, small, name="sphere")
        _sizes(gmsh, fine, coarse, [(2, s) for s in small], 2 * height_mm)

    return _mesh(build, order)


def line_charge_slab(
    height_mm: float,
    wire_mm: float,
    half_width_mm: float,
    length_mm: float,
    fine: float,
    coarse: float,
    order: int = 2,
) -> occ_mesh.TetMesh:
    """A slab [-L, L] x [0, length] x [-L, L] cut at z = 0 into `upper` and `lower`
    regions, with a thin wire of radius `wire_mm` along y at (x, z) = (0, h) removed
    (surface `wire`); the outer faces x = -+L and z = -+L are surface `outer`."""

    def build(gmsh):
        occ = gmsh.model.occ
        lo = occ.addBox(
            -half_width_mm, 0, -half_width_mm, 2 * half_width_mm, length_mm, half_width_mm
        )
        hi = occ.addBox(-half_width_mm, 0, 0, 2 * half_width_mm, length_mm, half_width_mm)
        wire = occ.addCylinder(0, 0, height_mm, 0, length_mm, 0, wire_mm)
        up, _ = occ.cut([(3, hi)], [(3, wire)])
        both, _ = occ.fragment([(3, lo)], up)
        occ.synchronize()
        upper = [d for d in both if occ.getCenterOfMass(3, d[1])[2] > 0]
        lower = [d for d in both if occ.getCenterOfMass(3, d[1])[2] < 0]
        gmsh.model.addPhysicalGroup(3, [d[1] for d in upper], name="upper")
        gmsh.model.addPhysicalGroup(3, [d[1] for d in lower], name="lower")
        w = _faces_where(gmsh, upper, lambda x, y, z: abs(z - height_mm) < 1e-6 and abs(x) < 1e-6)
        outer = _faces_where(
            gmsh,
            both,
            lambda x, y, z: (
                abs(abs(x) - half_width_mm) < 1e-6 or abs(abs(z) - half_width_mm) < 1e-6
            ),
        )
        gmsh.model.addPhysicalGroup(2, w, name="wire")
        gmsh.model.addPhysicalGroup(2, sorted(set(outer)), name="outer")
        _sizes(gmsh, fine, coarse, [(2, s) for s in w], half_width_mm)

    return _mesh(build, order)


def concentric_spheres(inner_mm: float, outer_mm: float, h: float, order: int) -> occ_mesh.TetMesh:
    """The shell between spheres of radii a < b (surfaces `inner`, `outer`), size h."""

    def build(gmsh):
        occ = gmsh.model.occ
        shell, _ = occ.cut(
            [(3, occ.addSphere(0, 0, 0, outer_mm))], [(3, occ.addSphere(0, 0, 0, inner_mm))]
        )
        occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [shell[0][1]], name="gap")
        r = {
            abs(s): np.linalg.norm(occ.getCenterOfMass(2, abs(s)))
            for _, s in gmsh.model.getBoundary(shell, oriented=False)
        }
        area = {s: occ.getMass(2, s) for s in r}
        inner = [s for s in area if area[s] < 2 * np.pi * (inner_mm + outer_mm) ** 2 / 2]
        gmsh.model.addPhysicalGroup(2, inner, name="inner")
        gmsh.model.addPhysicalGroup(2, [s for s in area if s not in inner], name="outer")
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)

    return _mesh(build, order)


def harmonic_box(h: float, order: int) -> occ_mesh.TetMesh:
    """The box [0, 1] x [0, pi] x [0, 0.5] (surfaces `x0`, `x1` at x = 0 and 1), size h:
    u = exp(x) cos(y) is harmonic and has zero normal derivative on its other faces."""

    def build(gmsh):
        occ = gmsh.model.occ
        box = [(3, occ.addBox(0, 0, 0, 1.0, np.pi, 0.5))]
        occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [box[0][1]], name="box")
        gmsh.model.addPhysicalGroup(
            2, _faces_where(gmsh, box, lambda x, y, z: abs(x) < 1e-9), name="x0"
        )
        gmsh.model.addPhysicalGroup(
            2, _faces_where(gmsh, box, lambda x, y, z: abs(x - 1) < 1e-9), name="x1"
        )
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)

    return _mesh(build, order)
