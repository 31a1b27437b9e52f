"""Reduce: inward offset of a closed mesh by the cover thickness, far fewer triangles.

A signed distance (positive inside, mm) is sampled on a regular grid: exact
point-to-triangle distances in a band around the offset level, nearest-vertex distances
elsewhere, sign by vertical ray parity. manifold3d's level set then extracts the surface
at `level = cover_mm` with an edge length chosen for the requested triangle count.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import GeometryError
from fruitcli.geometry.mesh import winding
from fruitcli.geometry.mesh.distance import TreeDistance, grid_vertex_distance

if TYPE_CHECKING:
    import manifold3d

# level-set triangles per mm^2 of surface at edge length e: TRIANGLES_PER_AREA / e^2
TRIANGLES_PER_AREA = 3.4
# the level set aims at this many times the requested count; simplify() takes it down
OVERSAMPLE = 2.0
# distance grid spacing as a fraction of the level-set edge length
GRID_PER_EDGE = 0.45
# pieces of the offset smaller than this fraction of the largest are dropped as islands
ISLAND_VOLUME_FRACTION = 0.01
# largest simplification tolerance, as a fraction of the level-set edge length
SIMPLIFY_MAX_PER_EDGE = 0.15
SIMPLIFY_STEPS = 8
# layers whose cross-section area is within this fraction of the largest form the "equator"
EQUATOR_AREA_FRACTION = 0.98


@dataclass
class Reduced:
    """The reduced body: manifold3d.Manifold, plus facts for the report."""

    body: manifold3d.Manifold
    edge_mm: float
    grid_mm: float
    dropped_islands: int
    equator_z_mm: float
    islands: list = field(default_factory=list)
    winding_range: tuple[float, float] = (0.0, 1.0)
    inside_volume_mm3: float = 0.0
    filled_pinches: list = field(default_factory=list)


def signed_distance_grid(
    vertices: np.ndarray,
    faces: np.ndarray,
    spacing_mm: float,
    level_mm: float,
    pad_mm: float,
    dist: TreeDistance | None = None,
    inside: Inside | None = None,
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Signed distance (positive inside) on a grid; returns (axes (x, y, z), sdf (nx, ny, nz),
    winding number (nx, ny, nz)).

    The distance is to the surface (`vertices`, `faces`: the faces that bound the inside)
    and to the caps that close its holes; exact within `2 * spacing_mm` of `level_mm`, a
    nearest-vertex bound elsewhere, clamped to `level_mm + 3 * spacing_mm` far from the
    surface. The sign is the winding number's (`inside`: the whole artist surface; default
    these faces).
    """
    from scipy.spatial import cKDTree

    lo = vertices.min(axis=0) - pad_mm
    hi = vertices.max(axis=0) + pad_mm
    axes = [
        lo[k] + spacing_mm * np.arange(int(np.ceil((hi[k] - lo[k]) / spacing_mm)) + 1)
        for k in range(3)
    ]
    shape = tuple(len(a) for a in axes)
    inside = inside or Inside(vertices, faces)
    band = level_mm + 3.0 * spacing_mm
    radius = winding.EXACT_BAND_SPACINGS * spacing_mm
    dist = dist or TreeDistance(vertices, faces)
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    # a closed surface's winding number is counted exactly along lines: no band needed
    closed = inside.wn.closed
    d = grid_vertex_distance(dist.vertices, axes, band if closed else max(band, radius))
    near = None
    if not closed:
        near = (
            d < radius
            if inside.tree is None
            else grid_vertex_distance(inside.wn.vertices, axes, radius) < radius
        )
        near = near.reshape(shape)
    w = winding.grid_winding(inside.wn, axes, near)
    d = np.minimum(d, band)
    cap_tree = None
    if inside.caps:
        caps = winding.cap_points(axes, w, dist.nearest_vertex_distance)
        inside.cap_points = caps
        if len(caps):
            cap_tree = cKDTree(caps, balanced_tree=False, compact_nodes=False)
            d = np.minimum(d, cap_tree.query(pts, distance_upper_bound=band)[0])
    is_in = w.ravel() > winding.INSIDE
    sdf = np.where(is_in, d, -d)
    level = np.nonzero(np.abs(sdf - level_mm) < 2.0 * spacing_mm)[0]
    if len(level):
        _, exact, _ = dist.closest(pts[level])
        if cap_tree is not None:
            exact = np.minimum(exact, cap_tree.query(pts[level])[0])
        sdf[level] = np.where(is_in[level], exact, -exact)
    return axes, sdf.reshape(shape), w


class Inside:
    """What decides inside and outside: the winding number of the whole artist surface;
    when only some of its faces bound the inside (overlapping parts, fins), a KD-tree over
    all its vertices (the winding number jumps at every face); when it has holes, caps
    (where the winding number crosses 1/2 away from the surface) join the distance."""

    def __init__(
        self,
        vertices: np.ndarray,
        faces: np.ndarray,
        all_faces_bound: bool = True,
        holes: bool = False,
    ):
        from scipy.spatial import cKDTree

        self.wn = winding.Winding(vertices, faces)
        self.tree = (
            None if all_faces_bound else cKDTree(vertices, balanced_tree=False, compact_nodes=False)
        )
        self.caps = bool(holes)
        self.cap_points = np.zeros((0, 3))


def _trilinear(axes: Sequence[np.ndarray], sdf: np.ndarray):
    """A Python callable f(x, y, z) interpolating `sdf` (what manifold's level set calls)."""
    x0, y0, z0 = (float(a[0]) for a in axes)
    h = float(axes[0][1] - axes[0][0])
    inv = 1.0 / h
    nx, ny, nz = sdf.shape
    flat = sdf.ravel().tolist()
    sy, sx = nz, ny * nz
    outside = float(sdf.min())

    def f(x: np.ndarray, y: np.ndarray, z: np.ndarray):
        fx, fy, fz = (x - x0) * inv, (y - y0) * inv, (z - z0) * inv
        i, j, k = int(fx), int(fy), int(fz)
        if i < 0 or j < 0 or k < 0 or i >= nx - 1 or j >= ny - 1 or k >= nz - 1:
            return outside
        tx, ty, tz = fx - i, fy - j, fz - k
        b = i * sx + j * sy + k
        c00 = flat[b] + (flat[b + sx] - flat[b]) * tx
        c10 = flat[b + sy] + (flat[b + sx + sy] - flat[b + sy]) * tx
        c01 = flat[b + 1] + (flat[b + sx + 1] - flat[b + 1]) * tx
        c11 = flat[b + sy + 1] + (flat[b + sx + sy + 1] - flat[b + sy + 1]) * tx
        c0 = c00 + (c10 - c00) * ty
        c1 = c01 + (c11 - c01) * ty
        return c0 + (c1 - c0) * tz

    return f


def edge_for_faces(area_mm2: float, faces: float) -> float:
    """Level-set edge length (mm) expected to give about `faces` triangles on `area_mm2`."""
    return float(np.sqrt(TRIANGLES_PER_AREA * area_mm2 / max(int(faces), 1)))


def surface_area(vertices: np.ndarray, faces: np.ndarray) -> float:
    tri = vertices[faces]
    return float(
        0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    )


def grid_for_faces(vertices: np.ndarray, faces: np.ndarray, target_faces: int) -> float:
    """Spacing (mm) of the signed-distance grid `reduce_body` uses for `target_faces`."""
    return GRID_PER_EDGE * edge_for_faces(surface_area(vertices, faces), OVERSAMPLE * target_faces)


GRID_BYTES_PER_POINT = 64.0
"""Memory the signed-distance grid and its reduction take per grid point (bytes; measured:
1.0 GB for 12.7 M points, 5.6 GB for 83 M, the process's baseline included)."""


def grid_points(vertices: np.ndarray, faces: np.ndarray, target_faces: int) -> float:
    """Points of the signed-distance grid `reduce_body` samples for `target_faces`
    (its spacing over the surface's bounding box padded as `reduce_body` pads it)."""
    h = grid_for_faces(vertices, faces, target_faces)
    extent = np.ptp(vertices, axis=0) + 4.0 * h
    return float(np.prod(np.ceil(extent / h) + 1.0))


def reduce_body(
    vertices: np.ndarray,
    faces: np.ndarray,
    cover_mm: float,
    target_faces: int,
    source: str = "mesh",
    dist: TreeDistance | None = None,
    cover_name: str = "--cover-mm",
    inside: Inside | None = None,
) -> Reduced:
    """Offset a surface inward by `cover_mm` with about `target_faces` triangles
    (`cover_name`: how the user sets cover_mm, named in errors). `vertices`, `faces`: the
    faces that bound the inside; `inside`: what decides inside (default: these faces)."""
    import manifold3d

    edge = edge_for_faces(surface_area(vertices, faces), OVERSAMPLE * target_faces)
    h = GRID_PER_EDGE * edge
    pad = 2.0 * h
    axes, sdf, w = signed_distance_grid(vertices, faces, h, cover_mm, pad, dist, inside)
    deep = (sdf > h) & (w > winding.DEEP_INSIDE)
    if not deep.any():
        raise GeometryError(
            f"{source}: the mesh has no inside: its winding number reaches only "
            f"{float(w[sdf > h].max(initial=w.min())):.2f} away from the surface (a body "
            f"reaches {winding.DEEP_INSIDE:g} to 1) on a grid of {h:.2g} mm, as for an open "
            "sheet or a plane, or a closed body thinner than about "
            f"{2 * h:.2g} mm; give a sheet a thickness in a modeller, or ask for more "
            "triangles (--faces, [tracks].faces) for a finer grid"
        )
    if not (sdf > cover_mm).any():
        where = _xyz(axes, int(np.argmax(sdf)))
        raise GeometryError(
            f"{source}: an inward offset of {cover_mm:g} mm consumes the whole body: it is "
            f"at most {2 * float(sdf.max()):.2f} mm thick (at {where} mm), thinner than twice "
            f"the cover; use a smaller {cover_name}"
        )
    lo = [float(a[0]) for a in axes]
    hi = [float(a[-1]) for a in axes]
    body = manifold3d.Manifold.level_set(_trilinear(axes, sdf), lo + hi, edge, cover_mm)
    if body.status() != manifold3d.Error.NoError or body.is_empty():
        raise GeometryError(
            f"{source}: an inward offset of {cover_mm:g} mm consumes the whole "
            f"body (use a smaller {cover_name})"
        )
    pieces = sorted(body.decompose(), key=lambda m: -m.volume())
    big = pieces[0].volume()
    kept = [p for p in pieces if p.volume() >= ISLAND_VOLUME_FRACTION * big]
    if len(kept) > 1:
        thick, where = neck(axes, sdf, cover_mm)
        if thick is None:
            raise GeometryError(
                f"{source}: the mesh encloses {len(kept)} separate bodies (their insides do "
                f"not touch; the two largest around {where} mm); expected one casting piece: "
                "join them or delete the extra bodies"
            )
        raise GeometryError(
            f"{source}: an inward offset of {cover_mm:g} mm pinches the body apart into "
            f"{len(kept)} pieces: the feature joining them at {where} mm is only "
            f"{thick:.2f} mm thick, thinner than twice the cover; use a smaller {cover_name} "
            "(or thicken that feature)"
        )
    islands = [(float(p.volume()), _centre(p)) for p in pieces[1:]]
    body = simplify_to(pieces[0], target_faces, SIMPLIFY_MAX_PER_EDGE * edge)
    body, cut_off = _drop_pinched_shells(body)
    islands += cut_off
    body, filled = _fill_pinched_edges(body, max(PINCH_RADIUS_EDGE * edge, PINCH_RADIUS_MIN_MM))
    if sum(v for v, _ in cut_off) >= ISLAND_VOLUME_FRACTION * body.volume():
        v, at = max(cut_off)
        raise GeometryError(
            f"{source}: an inward offset of {cover_mm:g} mm pinches off a piece of {v:.0f} "
            f"mm^3 at {at} mm: the feature joining it is thinner than twice the cover; use a "
            f"smaller {cover_name} (or thicken that feature)"
        )
    # equator: the height of the largest horizontal cross-section of the reduced body
    area_z = (sdf > cover_mm).sum(axis=(0, 1)).astype(float)
    plateau = np.nonzero(area_z >= EQUATOR_AREA_FRACTION * area_z.max())[0]
    equator = float(np.median(axes[2][plateau]))
    inside_w = w > winding.INSIDE
    return Reduced(
        body=body,
        edge_mm=edge,
        grid_mm=h,
        dropped_islands=len(islands),
        islands=[{"volume_mm3": round(v, 3), "at_mm": at} for v, at in islands],
        equator_z_mm=equator,
        winding_range=(float(w.min()), float(w.max())),
        inside_volume_mm3=float(inside_w.sum()) * h**3,
        filled_pinches=filled,
    )


def _centre(m: manifold3d.Manifold) -> str:
    """'(x, y, z)' of a Manifold's bounding-box centre, in mm."""
    b = m.bounding_box()
    return "(" + ", ".join(f"{0.5 * (b[k] + b[k + 3]):.1f}" for k in range(3)) + ")"


def _drop_pinched_shells(body: manifold3d.Manifold):
    """Split a Manifold into its edge-connected shells (manifold3d keeps shells that touch
    at one vertex together; a mesh file reader does not) and keep the largest.
    Returns (body, [(volume mm^3, centre) of each shell dropped])."""
    from fruitcli.geometry.mesh.load import edge_shells

    v, f = manifold_arrays(body)
    labels = edge_shells(f, len(v))
    if labels.max() == 0:
        return body, []
    tri = v[f]
    six_vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
    vol = np.bincount(labels, six_vol) / 6.0
    big = int(np.argmax(vol))
    out = []
    for k in range(len(vol)):
        if k != big:
            c = tri[labels == k].reshape(-1, 3)
            mid = 0.5 * (c.min(axis=0) + c.max(axis=0))
            out.append((float(vol[k]), "(" + ", ".join(f"{x:.1f}" for x in mid) + ")"))
    keep = f[labels == big]
    used, inv = np.unique(keep, return_inverse=True)
    return to_manifold64(v[used], inv.reshape(-1, 3)), out


PINCH_RADIUS_EDGE = 0.25
"""Radius of the capsule that fills a pinch, as a fraction of the level set's edge."""
PINCH_RADIUS_MIN_MM = 0.2


def _fill_pinched_edges(body: manifold3d.Manifold, radius_mm: float, rounds: int = 5):
    """Fill the places where the offset surface touches itself along an edge.

    manifold3d keeps the two sheets of such a pinch apart by duplicated vertices; a mesh
    file cannot, and reloads the edge with four faces (not closed). Each pinched edge is
    filled with a capsule of `radius_mm` (mm) around it, a local thickening of a place
    that is zero thick. Returns (body, ['(x, y, z)' mm of each capsule's centre])."""
    import manifold3d

    from fruitcli.geometry.mesh.export import weld_float32
    from fruitcli.geometry.mesh.load import edge_keys, edge_use

    ball = np.asarray(manifold3d.Manifold.sphere(radius_mm, 12).to_mesh().vert_properties)
    filled = []
    for _ in range(rounds):
        v, f = weld_float32(*manifold_arrays(body))
        edges, keys = edge_keys(f)
        shared = edge_use(f) != 2
        _, once = np.unique(keys[shared], return_index=True)
        pinched = v[edges[shared][once]]  # (k, 2, 3): both ends of each pinched edge
        if not len(pinched):
            break
        capsules = [
            manifold3d.Manifold.hull_points(np.concatenate([ball[:, :3] + end for end in ends]))
            for ends in pinched
        ]
        body = manifold3d.Manifold.batch_boolean([body, *capsules], manifold3d.OpType.Add)
        filled += ["(" + ", ".join(f"{x:.1f}" for x in ends.mean(axis=0)) + ")" for ends in pinched]
    return body, filled


def to_manifold64(vertices: np.ndarray, faces: np.ndarray) -> manifold3d.Manifold:
    """A manifold3d.Manifold from float64 arrays (no rounding to float32)."""
    import manifold3d

    return manifold3d.Manifold(
        manifold3d.Mesh64(
            np.ascontiguousarray(vertices, dtype=float),
            np.ascontiguousarray(faces, dtype=np.uint64),
        )
    )


def _xyz(axes: Sequence[np.ndarray], flat_index: int) -> str:
    """'(x, y, z)' of a grid point, in mm."""
    ijk = np.unravel_index(flat_index, tuple(len(a) for a in axes))
    return "(" + ", ".join(f"{float(axes[k][ijk[k]]):.1f}" for k in range(3)) + ")"


def neck(
    axes: list[np.ndarray], sdf: np.ndarray, cover_mm: float, steps: int = 10
) -> tuple[float | None, str]:
    """Where the offset pinches the body apart: the thickness (mm, twice the largest level
    at which the two largest pieces of {sdf > level} are still joined) and the grid point
    '(x, y, z)' at that level joining them. (None, 'A and B') when the pieces are not
    joined even inside the body: separate bodies around A and B."""
    from scipy import ndimage

    def pieces(level: float):
        lab, n = ndimage.label(sdf > level)
        if n < 2:
            return lab, None
        size = np.bincount(lab.ravel())[1:]
        return lab, 1 + np.argsort(-size)[:2]

    lab, two = pieces(cover_mm)
    if two is None:
        return 2 * cover_mm, "(unknown)"
    a_pts = np.argwhere(lab == two[0])
    b_pts = np.argwhere(lab == two[1])
    lab0, _ = pieces(0.0)
    if lab0[tuple(a_pts[0])] != lab0[tuple(b_pts[0])]:
        at = [
            _xyz(axes, int(np.ravel_multi_index(tuple(p.mean(axis=0).astype(int)), sdf.shape)))
            for p in (a_pts, b_pts)
        ]
        return None, " and ".join(at)
    lo, hi = 0.0, cover_mm  # joined at lo (inside the body), apart at hi
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        lab_m, _ = pieces(mid)
        if lab_m[tuple(a_pts[0])] == lab_m[tuple(b_pts[0])]:
            lo = mid
        else:
            hi = mid
    from scipy.spatial import cKDTree

    ring = np.argwhere((sdf > lo) & (sdf <= hi + 0.5 * (hi - lo) + 1e-9))
    if len(ring) == 0:
        return 2 * lo, "(unknown)"
    da, _ = cKDTree(a_pts).query(ring)
    db, _ = cKDTree(b_pts).query(ring)
    k = ring[int(np.argmin(np.maximum(da, db)))]
    flat = int(np.ravel_multi_index(tuple(k), sdf.shape))
    return 2 * lo, _xyz(axes, flat)


def simplify_to(
    body: manifold3d.Manifold, target_faces: int, max_tol_mm: float
) -> manifold3d.Manifold:
    """Simplify a Manifold to about `target_faces` triangles (bisection on the tolerance)."""
    if body.num_tri() <= target_faces:
        return body
    lo, hi = 0.0, max_tol_mm
    best = body.simplify(hi)
    if best.num_tri() >= target_faces:
        return best
    for _ in range(SIMPLIFY_STEPS):
        mid = 0.5 * (lo + hi)
        cand = body.simplify(mid)
        if cand.num_tri() > target_faces:
            lo = mid
        else:
            hi, best = mid, cand
    return best


def manifold_arrays(m: manifold3d.Manifold) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) float64 and faces (m, 3) int64 of a manifold3d.Manifold."""
    mesh = m.to_mesh64()
    v = np.asarray(mesh.vert_properties, dtype=float)[:, :3]
    return np.ascontiguousarray(v), np.asarray(mesh.tri_verts, dtype=np.int64)


def offset_error(
    reduced_v: np.ndarray,
    reduced_f: np.ndarray,
    artist_v: np.ndarray,
    artist_f: np.ndarray,
    cover_mm: float,
    n_samples: int = 20000,
    dist: TreeDistance | None = None,
    caps: np.ndarray | None = None,
) -> dict:
    """Hausdorff-type distance (mm) between the reduced surface and the ideal offset surface.

    reduced -> ideal: | distance to the artist surface - cover | at reduced vertices and
    face centres; ideal -> reduced: artist points moved inward by the cover along their
    normal (where that is a true offset point) measured to the reduced surface. `caps`
    (k, 3): points on the caps closing the artist surface's holes, part of its surface.
    """
    from scipy.spatial import cKDTree

    art = dist or TreeDistance(artist_v, artist_f)
    cap_tree = cKDTree(caps) if caps is not None and len(caps) else None

    def to_artist(p: np.ndarray):
        _, d, _ = art.closest(p)
        return d if cap_tree is None else np.minimum(d, cap_tree.query(p)[0])

    tri = reduced_v[reduced_f]
    q = np.concatenate([reduced_v, tri.mean(axis=1)])
    fwd = np.abs(to_artist(q) - cover_mm)
    atri = artist_v[artist_f]
    step = max(1, len(artist_f) // n_samples)
    atri = atri[::step]
    n = np.cross(atri[:, 1] - atri[:, 0], atri[:, 2] - atri[:, 0])
    norm = np.linalg.norm(n, axis=1)
    ok = norm > 0
    ideal = atri[ok].mean(axis=1) - cover_mm * n[ok] / norm[ok, None]
    d_ideal = to_artist(ideal)
    ideal = ideal[np.abs(d_ideal - cover_mm) < 1e-3 * max(cover_mm, 1.0) + 1e-6]
    back = np.zeros(0)
    if len(ideal):
        _, back, _ = TreeDistance(reduced_v, reduced_f).closest(ideal)
    h_fwd = float(fwd.max()) if len(fwd) else 0.0
    h_back = float(back.max()) if len(back) else 0.0
    worst = (
        q[int(np.argmax(fwd))] if h_fwd >= h_back or not len(back) else ideal[int(np.argmax(back))]
    )
    return {
        "hausdorff_mm": max(h_fwd, h_back),
        "reduced_to_ideal_max_mm": h_fwd,
        "ideal_to_reduced_max_mm": h_back,
        "reduced_to_ideal_mean_mm": float(fwd.mean()),
        "worst_at_mm": [round(float(x), 2) for x in worst],
    }
