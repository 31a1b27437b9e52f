"""The gmsh model of one yarn crossing: silicone under air, the yarns as holes.

Units: mm. The crossing is at x = y = 0, the skin's surface the plane z = 0 (silicone
below, air above). The Tx yarn runs along y at x = 0 (its neighbours at x = -+pitch_x),
the Rx yarn along x at y = 0 (neighbours at y = -+pitch_y); the Rx yarn is the upper one
(nearer the surface). The two touch the middle of their insulation at the cover depth:
Rx's axis at z = -(cover - r - t/2), Tx's at z = -(cover + r + t/2) (t: insulation).
The cell spans one pitch either side, x in [-px, px], y in [-py, py], so the
neighbouring yarns are half cylinders on its side faces (insulating faces mirror them
into whole ones); silicone reaches `BELOW_MM` under the Tx yarn, air `air_mm` above the
surface. Every outer face is insulating (zero normal field).

Physical groups: volumes ``silicone`` and ``air``; surfaces ``tx`` and ``rx`` (the
crossing's yarns), ``tx_side`` and ``rx_side`` (the neighbours), ``top`` (the air's
top face).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

BELOW_MM = 3.0
"""Silicone under the lower yarn (mm); its bottom face is insulating."""

FAR_SIZE_FACTOR = 3.0
"""Element size far from the crossing and the surface: this times `surface_size_mm`."""


@dataclass(frozen=True)
class CellSpec:
    """The crossing cell's geometry and mesh sizes (mm)."""

    pitch_x_mm: float
    pitch_y_mm: float
    cover_mm: float
    yarn_radius_mm: float
    insulation_mm: float
    air_mm: float
    crossing_size_mm: float  # element size at the crossing
    surface_size_mm: float  # element size at the surface near the crossing
    levels_mm: tuple = ()  # air planes z = level > 0 that get a node layer
    points_mm: tuple = ()  # (x, y, z) points on z = 0 or a level that get a node

    @property
    def rx_z_mm(self) -> float:
        return -(self.cover_mm - self.yarn_radius_mm - self.insulation_mm / 2)

    @property
    def tx_z_mm(self) -> float:
        return -(self.cover_mm + self.yarn_radius_mm + self.insulation_mm / 2)

    @property
    def bottom_z_mm(self) -> float:
        return self.tx_z_mm - self.yarn_radius_mm - BELOW_MM

    def to_dict(self) -> dict:
        return asdict(self)


def build(gmsh, spec: CellSpec) -> None:
    """Create the cell in the current (empty) gmsh model with its physical groups and
    size fields."""
    occ = gmsh.model.occ
    px, py, r = spec.pitch_x_mm, spec.pitch_y_mm, spec.yarn_radius_mm
    z0 = spec.bottom_z_mm
    sil = occ.addBox(-px, -py, z0, 2 * px, 2 * py, -z0)
    tops = sorted({float(z) for z in spec.levels_mm if 0 < z < spec.air_mm})
    air = [
        occ.addBox(-px, -py, z_lo, 2 * px, 2 * py, z_hi - z_lo)
        for z_lo, z_hi in zip([0.0, *tops], [*tops, spec.air_mm], strict=True)
    ]
    pad = 1.0  # cylinders overshoot the cell; cut back by the box
    tx = [
        occ.addCylinder(x, -py - pad, spec.tx_z_mm, 0, 2 * (py + pad), 0, r) for x in (0.0, -px, px)
    ]
    rx = [
        occ.addCylinder(-px - pad, y, spec.rx_z_mm, 2 * (px + pad), 0, 0, r) for y in (0.0, -py, py)
    ]
    cut, _ = occ.cut([(3, sil)], [(3, t) for t in tx + rx])
    both, _ = occ.fragment(cut, [(3, a) for a in air])
    occ.synchronize()
    _embed_points(gmsh, spec)
    vols_sil = [t for d, t in both if occ.getCenterOfMass(d, t)[2] < 0]
    vols_air = [t for d, t in both if occ.getCenterOfMass(d, t)[2] > 0]
    gmsh.model.addPhysicalGroup(3, vols_sil, name="silicone")
    gmsh.model.addPhysicalGroup(3, vols_air, name="air")
    groups: dict[str, list[int]] = {k: [] for k in ("tx", "rx", "tx_side", "rx_side", "top")}
    tol = 1e-6
    for _, s in gmsh.model.getBoundary(
        [(3, t) for t in vols_sil + vols_air], oriented=False, combined=False
    ):
        s = abs(s)
        lo = gmsh.model.getBoundingBox(2, s)
        (xa, ya, za), (xb, yb, zb) = lo[:3], lo[3:]
        zc = 0.5 * (za + zb)
        if za > spec.air_mm - tol:
            name = "top"
        elif abs(zc - spec.tx_z_mm) < r + tol and zb - za <= 2 * r + tol and za > z0 + tol:
            name = "tx" if max(abs(xa), abs(xb)) < px / 2 else "tx_side"
        elif abs(zc - spec.rx_z_mm) < r + tol and zb - za <= 2 * r + tol and zb < -tol:
            name = "rx" if max(abs(ya), abs(yb)) < py / 2 else "rx_side"
        else:
            continue
        if s not in groups[name]:
            groups[name].append(s)
    for name, tags in groups.items():
        gmsh.model.addPhysicalGroup(2, tags, name=name)
    _size_fields(gmsh, spec, groups["tx"] + groups["rx"])


def _embed_points(gmsh, spec: CellSpec) -> None:
    """A mesh node at each of `points_mm`, on the horizontal plane through it."""
    tol = 1e-6
    planes = {}
    for _, s in gmsh.model.getEntities(2):
        box = gmsh.model.getBoundingBox(2, s)
        if abs(box[5] - box[2]) < tol and box[3] - box[0] > spec.pitch_x_mm:
            planes[round(box[2], 6)] = s
    by_plane: dict[int, list[int]] = {}
    for x, y, z in spec.points_mm:
        s = planes.get(round(float(z), 6))
        if s is None:
            raise ValueError(f"no plane at z = {z} for an embedded point")
        by_plane.setdefault(s, []).append(gmsh.model.occ.addPoint(x, y, z))
    gmsh.model.occ.synchronize()
    for s, pts in by_plane.items():
        gmsh.model.mesh.embed(0, pts, 2, s)


def _size_fields(gmsh, spec: CellSpec, yarn_surfaces: list[int]) -> None:
    """Fine at the crossing, `surface_size_mm` along the yarns and on the surface near
    the crossing, coarser away from both."""
    f = gmsh.model.mesh.field
    r = spec.yarn_radius_mm
    far = FAR_SIZE_FACTOR * spec.surface_size_mm
    ball = f.add("Ball")
    for key, val in (
        ("XCenter", 0.0),
        ("YCenter", 0.0),
        ("ZCenter", -spec.cover_mm),
        ("Radius", 2 * r),
        ("Thickness", 2 * r),
        ("VIn", spec.crossing_size_mm),
        ("VOut", far),
    ):
        f.setNumber(ball, key, val)
    dist = f.add("Distance")
    f.setNumbers(dist, "SurfacesList", yarn_surfaces)
    yarn = f.add("Threshold")
    for key, val in (
        ("SizeMin", min(r / 2, spec.surface_size_mm)),
        ("SizeMax", far),
        ("DistMin", 0.0),
        ("DistMax", 3 * spec.cover_mm),
    ):
        f.setNumber(yarn, key, val)
    f.setNumber(yarn, "InField", dist)
    near = f.add("MathEval")
    reach = max(spec.pitch_x_mm, spec.pitch_y_mm) / 2
    f.setString(
        near,
        "F",
        f"{spec.surface_size_mm} + {far - spec.surface_size_mm} * "
        f"Min(1, Max(Abs(z) - 1, 0) / {spec.cover_mm} "
        f"+ Sqrt(x*x + y*y) / {reach} / 2)",
    )
    mn = f.add("Min")
    f.setNumbers(mn, "FieldsList", [ball, yarn, near])
    f.setAsBackgroundMesh(mn)
    for key in ("MeshSizeFromPoints", "MeshSizeFromCurvature", "MeshSizeExtendFromBoundary"):
        gmsh.option.setNumber(f"Mesh.{key}", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", far)
