"""The gmsh model of one yarn crossing: silicone under air, the yarns as holes.

Units: mm. The crossing is at x = y = 0, the skin's surface the plane z = 0 (silicone
below, air above). The Tx yarn runs along y at x = 0 (its neighbours at x = -+pitch_x),
the Rx yarn along x at y = 0 (neighbours at y = -+pitch_y); the Rx yarn is the upper one
(nearer the surface). The two touch the middle of their insulation at the cover depth:
Rx's axis at z = -(cover - r - t/2), Tx's at z = -(cover + r + t/2) (t: insulation).
The cell spans `reach` pitches either side, x in [-n px, n px], y in [-n py, n py]
(n = reach), with a yarn every pitch: the yarns at -+n pitches are half cylinders on its
side faces (insulating faces mirror them into whole ones), the others whole, so the
cell holds (2n - 1)^2 crossings; silicone reaches `below_mm` (default `BELOW_MM`) under
the Tx yarns, air `air_mm` above the surface and, for a pad with air behind it,
`back_air_mm` under the silicone (default none: the silicone's bottom face is the
cell's). Every outer face is insulating (zero normal field): no ground plane anywhere.

Physical groups: volumes ``silicone`` and ``air``; surfaces ``tx`` and ``rx`` (the
centre crossing's yarns), ``tx+1``, ``tx-1``, ``rx+1``, ... (the yarns a pitch, two
pitches, ... from it inside the cell), ``tx_side`` and ``rx_side`` (the yarns on the
side faces), ``top`` (the air's top face).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from types import ModuleType

BELOW_MM = 3.0
"""Silicone under the lower yarn (mm) by default; its bottom face is insulating."""

YARN_SIZE_RADII = 0.5
"""Element size along the yarns away from the crossings, in yarn radii (the crossings
themselves get `crossing_size_mm`)."""

YARN_REACH_COVERS = 2.0
"""Distance from the yarns (in covers) over which the size grows to the far size."""

OUTER_BALL_RADII = 1.0
"""Radius (in yarn radii) of the ball of `crossing_size_mm` at the crossings around the
centre one, whose is 2 radii: they keep the size in the insulation's gap and coarsen
sooner (they see the object from afar, where dC is a change in the fringing field)."""

AIR_GROWTH_MM = 10.0
"""Height over which the air's elements grow from the surface size to the far size above
the touch box (where the objects' tips are at the table's gaps)."""

FAR_SIZE_FACTOR = 3.0
"""Element size far from the crossing and the surface: this times `surface_size_mm`."""

COLUMN_SIZE_FACTOR = 1.0
"""Element size in the air column over the touch box (where the objects' tips come, up
to the highest level): this times `surface_size_mm`."""

CONTACT_SIZE_FACTOR = 0.6
"""Element size over the touch box from the yarns to `CONTACT_HEIGHT_MM` above the
surface (where the objects touch and come near): this times `surface_size_mm`."""

CONTACT_HEIGHT_MM = 1.0
"""Height of the finer part of the column (mm)."""

COLUMN_MARGIN_MM = 2.0
"""The column reaches this far beyond the touch box on each side and above the highest
level (the small indenter's radius and a little); its size grows to the far size over
as much."""


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
    reach: int = 1  # pitches either side of the centre crossing
    touch_box_mm: tuple = (0.0, 0.0)  # the surface is fine over [0, bx] x [0, by] and near
    below_mm: float = BELOW_MM  # silicone under the lower (Tx) yarn
    back_air_mm: float = 0.0  # air under the silicone (0: none, the silicone's face insulates)

    @property
    def yarn_names(self) -> tuple[list[str], list[str]]:
        """(Tx, Rx) names of the yarns inside the cell, from -(n - 1) to n - 1 pitches."""
        ks = range(-(self.reach - 1), self.reach)
        return [_yarn("tx", k) for k in ks], [_yarn("rx", k) for k in ks]

    @property
    def rx_z_mm(self) -> float:
        return -(self.cover_mm - self.yarn_radius_mm - self.insulation_mm / 2)

    @property
    def tx_z_mm(self) -> float:
        return -(self.cover_mm + self.yarn_radius_mm + self.insulation_mm / 2)

    @property
    def bottom_z_mm(self) -> float:
        return self.tx_z_mm - self.yarn_radius_mm - self.below_mm

    def to_dict(self) -> dict:
        return asdict(self)


def _yarn(kind: str, k: int) -> str:
    return kind if k == 0 else f"{kind}{k:+d}"


def build(gmsh: ModuleType, spec: CellSpec) -> None:
    """Create the cell in the current (empty) gmsh model with its physical groups and
    size fields."""
    occ = gmsh.model.occ
    n = spec.reach
    px, py, r = spec.pitch_x_mm, spec.pitch_y_mm, spec.yarn_radius_mm
    wx, wy = n * px, n * py  # half widths
    z0 = spec.bottom_z_mm
    sil = occ.addBox(-wx, -wy, z0, 2 * wx, 2 * wy, -z0)
    tops = sorted({float(z) for z in spec.levels_mm if 0 < z < spec.air_mm})
    air = [
        occ.addBox(-wx, -wy, z_lo, 2 * wx, 2 * wy, z_hi - z_lo)
        for z_lo, z_hi in zip([0.0, *tops], [*tops, spec.air_mm], strict=True)
    ]
    if spec.back_air_mm > 0:
        air.append(occ.addBox(-wx, -wy, z0 - spec.back_air_mm, 2 * wx, 2 * wy, spec.back_air_mm))
    pad = 1.0  # cylinders overshoot the cell; cut back by the box
    ks = range(-n, n + 1)
    tx = [occ.addCylinder(k * px, -wy - pad, spec.tx_z_mm, 0, 2 * (wy + pad), 0, r) for k in ks]
    rx = [occ.addCylinder(-wx - pad, k * py, spec.rx_z_mm, 2 * (wx + pad), 0, 0, r) for k in ks]
    cut, _ = occ.cut([(3, sil)], [(3, t) for t in tx + rx])
    both, _ = occ.fragment(cut, [(3, a) for a in air])
    occ.synchronize()
    _embed_points(gmsh, spec)
    vols_sil = [t for d, t in both if z0 < occ.getCenterOfMass(d, t)[2] < 0]
    vols_air = [t for d, t in both if t not in vols_sil]
    gmsh.model.addPhysicalGroup(3, vols_sil, name="silicone")
    gmsh.model.addPhysicalGroup(3, vols_air, name="air")
    tx_names, rx_names = spec.yarn_names
    names = (*tx_names, *rx_names, "tx_side", "rx_side", "top")
    groups: dict[str, list[int]] = {k: [] for k in names}
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
            k = round(0.5 * (xa + xb) / px)
            name = "tx_side" if abs(k) == n else _yarn("tx", k)
        elif abs(zc - spec.rx_z_mm) < r + tol and zb - za <= 2 * r + tol and zb < -tol:
            k = round(0.5 * (ya + yb) / py)
            name = "rx_side" if abs(k) == n else _yarn("rx", k)
        else:
            continue
        if s not in groups[name]:
            groups[name].append(s)
    for name, tags in groups.items():
        gmsh.model.addPhysicalGroup(2, tags, name=name)
    inner = [t for name in (*tx_names, *rx_names) for t in groups[name]]
    _size_fields(gmsh, spec, inner)


def _embed_points(gmsh: ModuleType, spec: CellSpec) -> None:
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


def _size_fields(gmsh: ModuleType, spec: CellSpec, yarn_surfaces: list[int]) -> None:
    """Fine at each crossing, `surface_size_mm` along the yarns and on the surface over
    the touch box (and the crossing), coarser away from them."""
    f = gmsh.model.mesh.field
    r = spec.yarn_radius_mm
    far = FAR_SIZE_FACTOR * spec.surface_size_mm
    balls = []
    ks = range(-(spec.reach - 1), spec.reach)
    for i in ks:
        for j in ks:
            ball = f.add("Ball")
            for key, val in (
                ("XCenter", i * spec.pitch_x_mm),
                ("YCenter", j * spec.pitch_y_mm),
                ("ZCenter", -spec.cover_mm),
                ("Radius", (2 if i == j == 0 else OUTER_BALL_RADII) * r),
                ("Thickness", 2 * r),
                ("VIn", spec.crossing_size_mm),
                ("VOut", far),
            ):
                f.setNumber(ball, key, val)
            balls.append(ball)
    dist = f.add("Distance")
    f.setNumbers(dist, "SurfacesList", yarn_surfaces)
    yarn = f.add("Threshold")
    for key, val in (
        ("SizeMin", min(YARN_SIZE_RADII * r, spec.surface_size_mm)),
        ("SizeMax", far),
        ("DistMin", 0.0),
        ("DistMax", YARN_REACH_COVERS * spec.cover_mm),
    ):
        f.setNumber(yarn, key, val)
    f.setNumber(yarn, "InField", dist)
    near = f.add("MathEval")
    reach = max(spec.pitch_x_mm, spec.pitch_y_mm) / 2
    bx, by = spec.touch_box_mm
    out_x = f"Max(Max(-x, x - {bx}), 0)"
    out_y = f"Max(Max(-y, y - {by}), 0)"
    f.setString(
        near,
        "F",
        f"{spec.surface_size_mm} + {far - spec.surface_size_mm} * "
        f"Min(1, Max(-z - 1, 0) / {spec.cover_mm} + Max(z - 1, 0) / {AIR_GROWTH_MM} "
        f"+ Sqrt({out_x} * {out_x} + {out_y} * {out_y}) / {reach})",
    )
    fields = [*balls, yarn, near]
    if bx > 0 or by > 0:
        m = COLUMN_MARGIN_MM
        top = min(max((float(z) for z in spec.levels_mm), default=0.0) + m, spec.air_mm)
        for factor, z_top in (
            (COLUMN_SIZE_FACTOR, top),
            (CONTACT_SIZE_FACTOR, min(CONTACT_HEIGHT_MM, top)),
        ):
            column = f.add("Box")
            for key, val in (
                ("VIn", factor * spec.surface_size_mm),
                ("VOut", far),
                ("XMin", -m),
                ("XMax", bx + m),
                ("YMin", -m),
                ("YMax", by + m),
                ("ZMin", -spec.cover_mm),
                ("ZMax", z_top),
                ("Thickness", m),
            ):
                f.setNumber(column, key, val)
            fields.append(column)
    mn = f.add("Min")
    f.setNumbers(mn, "FieldsList", fields)
    f.setAsBackgroundMesh(mn)
    for key in ("MeshSizeFromPoints", "MeshSizeFromCurvature", "MeshSizeExtendFromBoundary"):
        gmsh.option.setNumber(f"Mesh.{key}", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", far)
