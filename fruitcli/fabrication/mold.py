"""Two-part casting molds around a piece, with cores for its chambers (manifold3d).

A piece is a closed solid with one flat face on the parting plane z = zp (the casting
split plane): the tracked top lies above it, the lower half of the body below. Its mold is
a box `wall_mm` thicker than the piece, split at the parting plane into a shell (holding
the piece's impression: the yarn grooves of the top piece become ridges on its inner face)
and a plate (closing the flat face). Hemispherical registration keys on the plate fit
sockets in the shell `clearance_mm` larger. Each chamber inside the piece is cast around a
printable core: the chamber's solid plus a locating pin running from it through the plate
(a hole `clearance_mm` wider), which leaves an air inlet. A pour hole and vents run
straight up from the cavity's highest points through whichever part lies above them.

All lengths in mm, volumes in mm^3, as float64 manifold3d solids.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import GeometryError

if TYPE_CHECKING:
    import manifold3d as mf

CIRCLE_SEGMENTS = 48
"""Segments of the pins', channels' and keys' circles."""
GRID_MM = 1.5
"""Spacing (mm) of the height map searched for the cavity's highest points."""
VENT_SEPARATION_MM = 15.0
"""Vents are at least this far apart from each other and from the pour hole (mm)."""
TOUCH_MM = 1e-2
"""Solids that must join overlap by this much (mm): a channel reaches this far into the
cavity, an island of the shell this far into the plate."""


@dataclass
class MoldOptions:
    """Mold sizes in mm; `vents` is a count."""

    wall_mm: float = 4.0
    clearance_mm: float = 0.3
    key_radius_mm: float = 3.0
    pour_diameter_mm: float = 8.0
    vent_diameter_mm: float = 2.0
    pin_diameter_mm: float = 3.0
    vents: int = 4

    def check(self, names: dict[str, str]) -> None:
        """Refuse sizes a printed mold cannot have (`names`: how the user sets each)."""
        if not self.wall_mm >= 1.0:
            raise GeometryError(
                f"{names['wall_mm']}: expected a wall of at least 1 mm, got {self.wall_mm:g} mm"
            )
        if not 0.0 <= self.clearance_mm <= self.wall_mm:
            raise GeometryError(
                f"{names['clearance_mm']}: expected a clearance from 0 up to "
                f"the wall ({self.wall_mm:g} mm), got {self.clearance_mm:g} mm"
            )
        for key in ("key_radius_mm", "pour_diameter_mm", "vent_diameter_mm", "pin_diameter_mm"):
            if not getattr(self, key) > 0:
                raise GeometryError(
                    f"{names[key]}: expected a size > 0 mm, got {getattr(self, key)}"
                )
        if not self.key_radius_mm < self.wall_mm:
            raise GeometryError(
                f"{names['key_radius_mm']}: expected a key radius smaller than "
                f"the wall ({self.wall_mm:g} mm), got {self.key_radius_mm:g} mm"
            )
        if not 0 <= self.vents <= 16:
            raise GeometryError(f"{names['vents']}: expected 0 to 16 vents, got {self.vents}")


@dataclass
class Mold:
    """The parts of one piece's mold: name -> Manifold, and what a caster needs to know."""

    piece: str
    parts: dict = field(default_factory=dict)
    pull: dict = field(default_factory=dict)  # part -> unit pull direction or None
    silicone: mf.Manifold = None  # the cast piece (piece - cores)
    pour_mm: list = field(default_factory=list)
    vents_mm: list = field(default_factory=list)
    box_mm: list = field(default_factory=list)
    cores: list = field(default_factory=list)
    channels: mf.Manifold = None  # pour hole and vents


def box(lo: Sequence[float], hi: Sequence[float]) -> mf.Manifold:
    """An axis-aligned box Manifold from corner lo to corner hi (mm)."""
    import manifold3d as mf

    lo_mm, hi_mm = np.asarray(lo, float), np.asarray(hi, float)
    return mf.Manifold.cube(tuple(hi_mm - lo_mm)).translate(tuple(lo_mm))


def vertical_cylinder(x: float, y: float, z0: float, z1: float, r: float) -> mf.Manifold:
    import manifold3d as mf

    return mf.Manifold.cylinder(z1 - z0, r, r, CIRCLE_SEGMENTS).translate((x, y, z0))


def highest_points(
    piece: mf.Manifold,
    count: int,
    keep_off_mm: float,
    avoid: Iterable[tuple[np.ndarray, float]] = (),
) -> list[tuple[float, float, float]]:
    """The cavity's highest points: [(x, y, z)] mm, the highest first, then local maxima of
    the piece's top height at least VENT_SEPARATION_MM apart, at most `count` in all, each
    at least `keep_off_mm` inside the piece's outline (seen from above) and, for each
    (points (k, 2), distance mm) of `avoid` (the tracks, the pins), that far from them."""
    from scipy import ndimage

    from fruitcli.geometry.mesh.columns import top_z
    from fruitcli.geometry.tracks.reduce import manifold_arrays

    v, f = manifold_arrays(piece)
    lo, hi = v.min(axis=0), v.max(axis=0)
    xs = np.arange(lo[0] + GRID_MM / 2, hi[0], GRID_MM)
    ys = np.arange(lo[1] + GRID_MM / 2, hi[1], GRID_MM)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    h = top_z(v, f, np.c_[gx.ravel(), gy.ravel()]).reshape(gx.shape)
    inside = np.isfinite(h)
    margin = int(np.ceil(keep_off_mm / GRID_MM))
    if margin:
        inside = ndimage.binary_erosion(inside, iterations=margin)
    for pts_xy, dist_mm in avoid:
        if len(pts_xy):
            from scipy.spatial import cKDTree

            d, _ = cKDTree(np.asarray(pts_xy)[:, :2]).query(np.c_[gx.ravel(), gy.ravel()])
            inside &= d.reshape(gx.shape) >= dist_mm
    # maxima of the height where a channel may go (next to a blocked summit, the highest
    # allowed point beside it)
    hf = np.where(inside, h, -np.inf)
    peak = inside & (hf >= ndimage.maximum_filter(hf, size=3) - 1e-9)
    idx = np.argwhere(peak)
    order = np.argsort(-hf[peak], kind="stable")
    out: list[tuple[float, float, float]] = []
    for i, j in idx[order]:
        p = (float(xs[i]), float(ys[j]), float(h[i, j]))
        if all(np.hypot(p[0] - q[0], p[1] - q[1]) >= VENT_SEPARATION_MM for q in out):
            out.append(p)
            if len(out) >= count:
                break
    return out


def make_mold(
    name: str,
    piece: mf.Manifold,
    zp: float,
    side: int,
    chambers: list,
    opts: MoldOptions,
    tracks_xy: np.ndarray | None = None,
    track_radius_mm: float = 0.0,
) -> Mold:
    """The mold of `piece` (Manifold whose flat face lies on z = zp; `side` +1 if the piece
    lies above the plane, -1 below), with a core for each chamber (name, Manifold) that
    lies inside it. The pour hole and vents keep off the track centre points `tracks_xy`
    (k, 2) mm (a channel through a ridge would cut its groove) and off the pins."""
    import manifold3d as mf

    w, c, kr = opts.wall_mm, opts.clearance_mm, opts.key_radius_mm
    b = piece.bounding_box()
    lo, hi = np.array(b[:3]), np.array(b[3:])
    if side > 0 and abs(lo[2] - zp) > 1e-3 or side < 0 and abs(hi[2] - zp) > 1e-3:
        raise GeometryError(f"{name}: the piece does not rest on the parting plane z = {zp:.3f} mm")
    room = w + 2.0 * kr + c  # keys sit in the corners, outside the cavity
    x0, y0, x1, y1 = lo[0] - room, lo[1] - room, hi[0] + room, hi[1] + room
    far = hi[2] + w if side > 0 else lo[2] - w  # the shell's far face
    near = zp - side * w  # the plate's far face
    top_z = max(far, near) + 1.0  # where the pour hole and vents open
    shell_box = box((x0, y0, min(zp, far)), (x1, y1, max(zp, far)))
    plate_box = box((x0, y0, min(zp, near)), (x1, y1, max(zp, near)))
    keys, sockets = _keys(piece, (x0, y0, x1, y1), zp, w, kr, c)
    if len(keys) < 2:
        raise GeometryError(
            f"{name}: no room for two registration keys in the mold's corners; use a thicker wall"
        )
    mold = Mold(
        piece=name,
        box_mm=[
            float(x0),
            float(y0),
            float(min(far, near)),
            float(x1),
            float(y1),
            float(max(far, near)),
        ],
    )
    cores, pin_holes, pin_xy = _cores(name, piece, chambers, opts, near, zp, shell_box)
    shell = mf.Manifold.batch_boolean([shell_box, piece, *sockets], mf.OpType.Subtract)
    # whole spheres centred on the plate's face: their lower halves vanish in the plate (no
    # coplanar faces for the union to weld), their upper halves are the keys
    plate = mf.Manifold.batch_boolean([plate_box, *keys], mf.OpType.Add)
    # where the piece's surface dips below the parting plane (a hollow in the face that
    # should be flat) the shell box leaves an island between the piece and the plane: it
    # belongs to the plate
    loose = sorted(shell.decompose(), key=lambda m: -m.volume())
    if len(loose) > 1:
        shell = loose[0]
        # each island with a copy TOUCH_MM into the plate, so that the union welds
        grown = [i + i.translate((0.0, 0.0, -side * TOUCH_MM)) for i in loose[1:]]
        plate = mf.Manifold.batch_boolean([plate, *grown], mf.OpType.Add)
    if pin_holes:
        plate = mf.Manifold.batch_boolean([plate, *pin_holes], mf.OpType.Subtract)
    silicone = mf.Manifold.batch_boolean([piece, *[k for _, k in cores]], mf.OpType.Subtract)
    pts, channels = _channels(name, piece, opts, tracks_xy, track_radius_mm, pin_xy, top_z)
    mold.channels = mf.Manifold.batch_boolean(channels, mf.OpType.Add)
    shell = mf.Manifold.batch_boolean([shell, *channels], mf.OpType.Subtract)
    plate = mf.Manifold.batch_boolean([plate, *channels], mf.OpType.Subtract)
    mold.parts = {f"{name}_shell": shell, f"{name}_plate": plate}
    mold.pull = {
        f"{name}_shell": [0.0, 0.0, float(side)],
        f"{name}_plate": [0.0, 0.0, float(-side)],
    }
    for cname, core in cores:
        core = mf.Manifold.batch_boolean([core, *channels], mf.OpType.Subtract)
        mold.parts[f"{name}_core_{cname}"] = core
        mold.pull[f"{name}_core_{cname}"] = None
    mold.cores = [cname for cname, _ in cores]
    mold.silicone = silicone
    mold.pour_mm = [round(v, 3) for v in pts[0]]
    mold.vents_mm = [[round(v, 3) for v in p] for p in pts[1:]]
    for pname, part in mold.parts.items():
        if part.status() != mf.Error.NoError or part.is_empty():
            raise GeometryError(
                f"{name}: the mold part {pname} came out invalid ({part.status().name})"
            )
    return mold


def _keys(
    piece: mf.Manifold, outline: Sequence[float], zp: float, w: float, kr: float, c: float
) -> tuple[list, list]:
    """(keys, sockets): a registration sphere of radius `kr` mm in each corner of the
    mold's `outline` (x0, y0, x1, y1) mm on the parting plane z = zp that the piece leaves
    free, and its socket `c` mm wider; `w` the wall (mm)."""
    import manifold3d as mf

    x0, y0, x1, y1 = outline
    keys, sockets = [], []
    for kx, ky in (
        (x0 + w / 2 + kr, y0 + w / 2 + kr),
        (x1 - w / 2 - kr, y0 + w / 2 + kr),
        (x1 - w / 2 - kr, y1 - w / 2 - kr),
        (x0 + w / 2 + kr, y1 - w / 2 - kr),
    ):
        key = mf.Manifold.sphere(kr, CIRCLE_SEGMENTS).translate((kx, ky, zp))
        if not (key ^ piece).is_empty():
            continue  # the piece reaches this corner: no key there
        keys.append(key)
        sockets.append(mf.Manifold.sphere(kr + c, CIRCLE_SEGMENTS).translate((kx, ky, zp)))
    return keys, sockets


def _cores(
    name: str,
    piece: mf.Manifold,
    chambers: list,
    opts: MoldOptions,
    near: float,
    zp: float,
    shell_box: mf.Manifold,
):
    """(cores [(chamber, Manifold)], pin holes [Manifold], pin centres [(x, y)] mm): each
    chamber's part inside the piece with its locating pin to the plate's face z = `near`,
    and the pins' holes through the plate."""
    c = opts.clearance_mm
    cores, pin_holes, pin_xy = [], [], []
    for cname, whole in chambers:
        ch = whole ^ piece  # a chamber across the parting plane: a core in each half
        if ch.is_empty() or ch.volume() <= 1e-6 * whole.volume():
            continue
        cb = ch.bounding_box()
        cx, cy = 0.5 * (cb[0] + cb[3]), 0.5 * (cb[1] + cb[4])
        cz = 0.5 * (cb[2] + cb[5])
        r = opts.pin_diameter_mm / 2
        pin = vertical_cylinder(cx, cy, min(cz, near), max(cz, near), r)
        core = ch + pin
        if (
            not (core ^ (shell_box - piece)).is_empty()
            and (core ^ (shell_box - piece)).volume() > 1e-6
        ):
            raise GeometryError(
                f"chamber '{cname}': its locating pin would cross the {name} "
                "mold's shell (the straight path to the parting plane leaves "
                "the piece)"
            )
        cores.append((cname, core))
        pin_xy.append((cx, cy))
        pin_holes.append(vertical_cylinder(cx, cy, min(zp, near) - 1, max(zp, near) + 1, r + c))
    return cores, pin_holes, pin_xy


def _channels(
    name: str,
    piece: mf.Manifold,
    opts: MoldOptions,
    tracks_xy: np.ndarray | None,
    track_radius_mm: float,
    pin_xy: list,
    top: float,
):
    """(points, channels): the pour hole (first) and vents straight up from the cavity's
    highest points to z = `top` mm, off the track centre points and the pins."""
    # pour hole and vents: straight up from the cavity's highest points
    reach = opts.pour_diameter_mm / 2 + 0.3  # the widest channel, and a little
    avoid = [
        (
            np.zeros((0, 2)) if tracks_xy is None else np.asarray(tracks_xy)[:, :2],
            reach + track_radius_mm,
        ),
        (np.asarray(pin_xy).reshape(-1, 2), reach + opts.pin_diameter_mm / 2 + opts.clearance_mm),
    ]
    pts = highest_points(piece, 1 + opts.vents, opts.pour_diameter_mm / 2 + 0.5, avoid)
    if not pts:
        raise GeometryError(f"{name}: no room for a pour hole in the piece's outline")
    channels = [
        vertical_cylinder(
            x, y, z - 0.5, top, (opts.pour_diameter_mm if k == 0 else opts.vent_diameter_mm) / 2
        )
        for k, (x, y, z) in enumerate(pts)
    ]
    return pts, channels


def undercut_area(piece: mf.Manifold, zp: float, side: int, pull: dict) -> dict:
    """Per part with a pull direction, the area (mm^2) of the piece's surface that part
    touches and that faces away from its pull (an undercut that locks the part): the shell
    touches what lies off the parting plane, the plate the flat face on it."""
    from fruitcli.geometry.tracks.reduce import manifold_arrays

    v, f = manifold_arrays(piece)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(n, axis=1)
    n = n / np.maximum(2 * area[:, None], 1e-300)
    on_plane = np.all(np.abs(tri[:, :, 2] - zp) < 1e-4, axis=1)
    out = {}
    for pname, d in pull.items():
        if d is None:
            continue
        touches = on_plane if pname.endswith("_plate") else ~on_plane
        locks = touches & (n @ np.asarray(d) < -1e-6)
        out[pname] = round(float(area[locks].sum()), 3)
    return out


def assembled_cavity(mold: Mold) -> mf.Manifold:
    """The empty space the assembled mold encloses (box - all parts - the pour and vent
    channels), as a Manifold: what the silicone fills (plus the keys' and pins'
    clearance)."""
    import manifold3d as mf

    outer = box(mold.box_mm[:3], mold.box_mm[3:])
    return mf.Manifold.batch_boolean(
        [outer, *mold.parts.values(), mold.channels], mf.OpType.Subtract
    )
