"""Loading an artist's mesh as it is: any triangle surface in mm, with what was found.

The file is read (STL, OBJ, PLY, OFF, glTF/GLB; a scene's meshes are merged), scaled to
mm (its unit, then optionally to a given largest extent), and cleaned only in ways that
do not change the surface: duplicate vertices merged, degenerate and duplicate faces
dropped, face winding made consistent and outward. Holes, several parts, overlaps and
non-manifold edges are kept and counted: the inside is decided later by the winding number
(`fruitcli.geometry.mesh.winding`). Only what is not a mesh at all is refused here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import GeometryError
from fruitcli.geometry.mesh.units import MAX_EXTENT_MM, UNIT_TO_MM

if TYPE_CHECKING:
    import manifold3d

MESH_SUFFIXES = (".stl", ".obj", ".ply", ".off", ".glb", ".gltf")
MIN_EXTENT_MM = 2.0
"""A mesh read in mm and smaller than this across is refused: it is in m or cm."""
CLI_UNIT_HINT = "give its unit (--unit m or --unit cm) or its size (--fit-mm)"
SCENE_UNIT_HINT = 'set [geometry].unit = "m" (or "cm")'
SCENE_ARTIST_HINT = 'set [geometry].unit = "m" (or "cm") or [geometry].fit_mm'


@dataclass
class Surface:
    """An artist's surface in mm: vertices (n, 3) float64, faces (m, 3) int64, outward
    where it can be told, and what loading found and did."""

    vertices: np.ndarray
    faces: np.ndarray
    repairs: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    holes: int = 0
    largest_hole_perimeter_mm: float = 0.0
    parts: int = 1
    non_manifold_edges: int = 0
    faces_dropped: int = 0

    @property
    def closed(self) -> bool:
        """One part, no hole, every edge shared by exactly two faces."""
        return self.holes == 0 and self.parts == 1 and self.non_manifold_edges == 0

    def facts(self) -> dict:
        return {
            "holes": self.holes,
            "largest_hole_perimeter_mm": self.largest_hole_perimeter_mm,
            "parts": self.parts,
            "non_manifold_edges": self.non_manifold_edges,
            "faces_dropped_at_load": self.faces_dropped,
            "closed": self.closed,
        }


def check_extent(verts_mm: np.ndarray, unit: str, what: str, hint: str) -> None:
    """Refuse a mesh whose size (vertices in mm, read from a file in `unit`) says the
    unit is wrong: under MIN_EXTENT_MM read as mm (it is in metres or centimetres; `hint`
    says how to give its unit), over MAX_EXTENT_MM in any unit. `what` names the mesh
    (and where it was given)."""
    extent = float(np.ptp(verts_mm, axis=0).max())
    if unit == "mm" and extent < MIN_EXTENT_MM:
        raise GeometryError(
            f"{what} is only {extent:.3g} mm across, so it is not in millimetres; {hint}"
        )
    if extent > MAX_EXTENT_MM:
        raise GeometryError(
            f"{what} is {extent:.4g} mm across{'' if unit == 'any' else f' in {unit}'}, more than "
            f"{MAX_EXTENT_MM:g} mm: is that its unit?"
        )
    far = float(np.abs(verts_mm).max())
    if far > MAX_EXTENT_MM:  # 1e9 mm away, a float's step is 1e-7 mm: the carving fails
        raise GeometryError(
            f"{what} lies up to {far:.4g} mm from the origin, more than "
            f"{MAX_EXTENT_MM:g} mm; move it near the origin (the outputs "
            "are in the mesh's own coordinates)"
        )


STL_HEADER_BYTES = 84  # 80 bytes of text, then the triangle count (uint32, little-endian)
STL_TRIANGLE_BYTES = 50


def check_binary_stl(path: Path) -> None:
    """Refuse a binary STL whose header's triangle count does not match its size (a
    truncated file, or a header that lies), naming both; ASCII STL is left to the reader."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(1024)
    text = head.lstrip().lower().startswith(b"solid") and all(
        32 <= c < 127 or c in b"\t\r\n" for c in head
    )
    if text:
        return
    if size < STL_HEADER_BYTES:
        raise GeometryError(
            f"{path}: {size} bytes, shorter than a binary STL header ({STL_HEADER_BYTES} bytes)"
        )
    count = int.from_bytes(head[80:84], "little")
    expected = STL_HEADER_BYTES + STL_TRIANGLE_BYTES * count
    if size < expected or (count == 0 and size > STL_HEADER_BYTES):
        room = (size - STL_HEADER_BYTES) // STL_TRIANGLE_BYTES
        raise GeometryError(
            f"{path}: binary STL header says {count:,} triangles ({expected:,} bytes), "
            f"the file has {size:,} bytes (room for {room:,}): truncated, or its header's "
            "count is wrong"
        )


def read_mesh_file(path: str | Path) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Vertices (n, 3), faces (m, 3) and notes of a mesh file, in the file's own unit; the
    meshes of a scene (glTF, multi-object OBJ) are merged, with their transforms."""
    import trimesh

    path = Path(path)
    if not path.exists():
        raise GeometryError(f"{path}: file not found")
    if path.is_dir():
        raise GeometryError(
            f"{path}: is a folder (expected a mesh file: {', '.join(MESH_SUFFIXES)})"
        )
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise GeometryError(
            f"{path}: unknown mesh format '{path.suffix}' (expected {', '.join(MESH_SUFFIXES)})"
        )
    if path.stat().st_size == 0:
        raise GeometryError(f"{path}: empty file (expected a triangle mesh)")
    if path.suffix.lower() == ".stl":
        check_binary_stl(path)
    try:
        scene = trimesh.load(path, process=False, force="scene")
        parts = list(scene.dump()) if isinstance(scene, trimesh.Scene) else [scene]
    except IndexError:
        raise GeometryError(f"{path}: faces refer to missing vertices") from None
    except Exception as exc:
        # (a garbage binary STL makes trimesh try it as text, which may need a module
        # that is not installed: that says nothing about the file, so it is not shown)
        why = (
            ""
            if isinstance(exc, ImportError)
            else f" ({type(exc).__name__}: {(str(exc).splitlines() or [''])[0][:80]})"
        )
        raise GeometryError(
            f"{path}: cannot read as a {path.suffix[1:].upper()} mesh{why}; "
            "is it a triangle mesh file?"
        ) from None
    meshes = [p for p in parts if isinstance(p, trimesh.Trimesh) and len(p.faces)]
    if not meshes:
        points = sum(len(getattr(p, "vertices", [])) for p in parts)
        what = f" ({points} points only)" if points else ""
        raise GeometryError(f"{path}: no triangles found{what}; expected a triangle mesh")
    verts, faces, offset = [], [], 0
    for m in meshes:
        v = np.asarray(m.vertices, dtype=float)
        f = np.asarray(m.faces, dtype=np.int64)
        if f.min() < 0 or f.max() >= len(v):
            raise GeometryError(f"{path}: faces refer to missing vertices")
        verts.append(v)
        faces.append(f + offset)
        offset += len(v)
    notes = [f"merged the {len(meshes)} meshes of the file into one"] if len(meshes) > 1 else []
    all_v, all_f = np.concatenate(verts), np.concatenate(faces)
    if not np.isfinite(all_v).all():
        raise GeometryError(f"{path}: vertices contain NaN or infinite coordinates")
    return all_v, all_f, notes


def load_mesh(
    path: str | Path,
    unit: str | None = None,
    unit_hint: str = CLI_UNIT_HINT,
    fit_mm: float | None = None,
    fit_name: str = "--fit-mm",
) -> Surface:
    """Load `path` as a surface in mm: `unit` (mm, cm, m) first, then, if `fit_mm` is
    given, a uniform scale making its largest extent `fit_mm` mm (`fit_name` names that
    option in errors). Unless `unit` is cm or m or `fit_mm` is given the mesh must be at
    least MIN_EXTENT_MM across (`unit_hint` tells how to give its unit)."""
    path = Path(path)
    if unit is not None and unit not in UNIT_TO_MM:
        raise GeometryError(f"{path}: unknown unit '{unit}' (expected mm, cm or m)")
    if fit_mm is not None and not 0 < fit_mm <= MAX_EXTENT_MM:
        raise GeometryError(
            f"{fit_name}: expected a size > 0 and <= {MAX_EXTENT_MM:g} mm, got {fit_mm}"
        )
    verts, faces, notes = read_mesh_file(path)
    unit = unit or "mm"
    verts = verts * UNIT_TO_MM[unit]
    repairs = [f"scaled from {unit} to mm (x{UNIT_TO_MM[unit]:g})"] if unit != "mm" else []
    if fit_mm is not None:
        extent = float(np.ptp(verts, axis=0).max())
        if not extent > 0:
            raise GeometryError(f"{path}: all vertices coincide; there is nothing to scale")
        verts = verts * (fit_mm / extent)
        repairs.append(
            f"scaled by {fit_mm / extent:.6g} so that its largest extent is "
            f"{fit_mm:g} mm (from {extent:.4g} mm)"
        )
    check_extent(verts, "any" if fit_mm is not None else unit, f"{path}: the mesh", unit_hint)
    surf = clean(verts, faces, str(path))
    surf.repairs = repairs + surf.repairs
    surf.notes = notes + surf.notes
    return surf


def clean(verts: np.ndarray, faces: np.ndarray, source: str = "mesh") -> Surface:
    """Merge duplicate vertices, drop degenerate and duplicate faces, make the winding
    consistent and outward; count holes, parts and non-manifold edges."""
    import trimesh

    repairs = []
    merged = trimesh.Trimesh(verts, faces, process=False)
    merged.merge_vertices(merge_tex=True, merge_norm=True)
    merged.remove_unreferenced_vertices()
    if len(merged.vertices) < len(verts):
        repairs.append(f"merged {len(verts) - len(merged.vertices)} duplicate vertices")
    verts = np.asarray(merged.vertices, dtype=float)
    faces = np.asarray(merged.faces, dtype=np.int64)
    n_in = len(faces)
    tri = verts[faces]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    degenerate = (
        (faces[:, 0] == faces[:, 1])
        | (faces[:, 1] == faces[:, 2])
        | (faces[:, 0] == faces[:, 2])
        | (area2 == 0)
    )
    if degenerate.any():
        repairs.append(f"dropped {int(degenerate.sum())} degenerate faces (zero area)")
        faces = faces[~degenerate]
    if len(faces) == 0:
        raise GeometryError(f"{source}: every face has zero area (expected a triangle mesh)")
    sf = np.sort(faces, axis=1)
    n = int(faces.max()) + 1
    _, first = np.unique((sf[:, 0] * n + sf[:, 1]) * n + sf[:, 2], return_index=True)
    if len(first) < len(faces):
        repairs.append(f"dropped {len(faces) - len(first)} duplicate faces")
        faces = faces[np.sort(first)]
    labels = component_count(faces, len(verts))
    oriented, conflicts = orient_faces(faces)
    oriented, outward = _outward(verts, oriented, labels)
    flipped = int((oriented[:, 0] != faces[:, 0]).sum())
    if flipped:
        repairs.append(f"made the face winding consistent and outward ({flipped} faces flipped)")
    if conflicts:
        repairs.append(
            f"{conflicts} edges join faces whose winding cannot agree (a "
            "non-orientable surface); the winding number may be off there"
        )
    used = edge_use(oriented)
    holes, perimeter = hole_loops(verts, oriented)
    return Surface(
        vertices=verts,
        faces=oriented,
        repairs=repairs,
        notes=[],
        holes=holes,
        largest_hole_perimeter_mm=perimeter,
        parts=int(len(np.unique(labels))),
        non_manifold_edges=int((used > 2).sum() // 3),
        faces_dropped=n_in - len(oriented),
    )


def edge_keys(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Directed edges (3m, 2) in face order (ab of all faces, then bc, then ca) and their
    undirected keys (3m,)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    n = int(faces.max()) + 1
    return e, e.min(axis=1) * n + e.max(axis=1)


def edge_use(faces: np.ndarray) -> np.ndarray:
    """For each directed edge (3m,) in face order, how many faces use its undirected edge."""
    _, key = edge_keys(faces)
    _, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    return counts[inv]


def hole_loops(verts: np.ndarray, faces: np.ndarray) -> tuple[int, float]:
    """Holes of a surface: (number of boundary loops, largest loop perimeter in mm).

    Boundary edges are those used by exactly one face; loops are their connected sets.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e, _ = edge_keys(faces)
    b = e[edge_use(faces) == 1]
    if len(b) == 0:
        return 0, 0.0
    ids, inv = np.unique(b.ravel(), return_inverse=True)
    inv = inv.reshape(-1, 2)
    g = coo_matrix((np.ones(len(b)), (inv[:, 0], inv[:, 1])), shape=(len(ids),) * 2)
    n, lab = connected_components(g, directed=False)
    length = np.linalg.norm(verts[b[:, 0]] - verts[b[:, 1]], axis=1)
    per = np.bincount(lab[inv[:, 0]], length, minlength=n)
    return int(n), float(per.max())


def orient_faces(faces: np.ndarray) -> tuple[np.ndarray, int]:
    """Faces with winding made consistent across every edge shared by exactly two faces
    (each component keeps its first face's winding), and the number of such edges whose
    faces still disagree (0 unless the surface is not orientable).

    Without networkx (trimesh.repair.fix_winding needs it): faces are visited breadth
    first through shared edges, each flipped when it runs an edge the same way as the
    face it was reached from. Boundary and non-manifold edges join nothing.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order

    m = len(faces)
    e, key = edge_keys(faces)
    owner = np.tile(np.arange(m), 3)
    _, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    two = counts[inv] == 2
    idx = np.nonzero(two)[0]
    order = idx[np.argsort(key[idx], kind="stable")]
    a, b = order[0::2], order[1::2]
    same = e[a, 0] == e[b, 0]  # both faces run the edge the same way
    fa, fb = owner[a], owner[b]
    # relation +1 (same way: flip relative) or -1 (opposite: keep) per face pair
    r = np.where(same, 2.0, 1.0)
    rel = coo_matrix((np.r_[r, r], (np.r_[fa, fb], np.r_[fb, fa])), shape=(m, m)).tocsr()
    graph = (rel > 0).astype(np.int8)
    flip = np.zeros(m, dtype=bool)
    seen = np.zeros(m, dtype=bool)
    for root in range(m):
        if seen[root]:
            continue
        visit, pred = breadth_first_order(graph, root, directed=False)
        seen[visit] = True
        f = visit[1:]
        if f.size == 0:  # an isolated face: nothing to orient it against
            continue
        p = pred[f]
        r = (np.asarray(rel[f, p]).ravel() % 2 == 0).tolist()  # 2 (or 4): same way
        fl = flip.tolist()
        for fi, pi, ri in zip(f.tolist(), p.tolist(), r, strict=True):
            fl[fi] = fl[pi] ^ ri
        flip = np.asarray(fl, dtype=bool)
    conflicts = int((flip[fa] ^ flip[fb] ^ same).sum())
    out = faces.copy()
    out[flip] = out[flip][:, ::-1]
    return out, conflicts


def _outward(verts: np.ndarray, faces: np.ndarray, labels: np.ndarray):
    """Flip each part whose signed volume (about its own centre) is negative: an outward
    surface encloses a positive volume. Returns (faces, per-part signed volumes mm^3)."""
    tri = verts[faces]
    nlab = int(labels.max()) + 1
    cnt = np.bincount(labels, minlength=nlab)
    centre = (
        np.stack(
            [np.bincount(labels, tri[:, :, k].mean(axis=1), minlength=nlab) for k in range(3)],
            axis=1,
        )
        / np.maximum(cnt, 1)[:, None]
    )
    t = tri - centre[labels][:, None, :]
    six = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2]))
    vol = np.bincount(labels, six, minlength=nlab) / 6.0
    inverted = vol[labels] < 0
    out = faces.copy()
    out[inverted] = out[inverted][:, ::-1]
    return out, np.abs(vol)


def component_count(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Connected-component label per face (faces joined through shared vertices)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    rows = np.repeat(np.arange(len(faces)), 3)
    graph = coo_matrix(
        (np.ones(len(rows)), (rows, faces.ravel() + len(faces))),
        shape=(len(faces) + n_vertices,) * 2,
    )
    _, labels = connected_components(graph, directed=False)
    labels = labels[: len(faces)]
    return np.unique(labels, return_inverse=True)[1].ravel()


def to_manifold(vertices: np.ndarray, faces: np.ndarray) -> manifold3d.Manifold:
    """A manifold3d.Manifold from arrays (vertices float64 mm, faces int)."""
    import manifold3d

    mesh = manifold3d.Mesh(
        np.ascontiguousarray(vertices, dtype=np.float32),
        np.ascontiguousarray(faces, dtype=np.uint32),
    )
    return manifold3d.Manifold(mesh)


def edge_shells(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Shell label (m,) per face, faces joined through shared edges (not single vertices),
    labels numbered from 0."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, edge_id = np.unique(e[:, 0] * n_vertices + e[:, 1], return_inverse=True)
    owner = np.tile(np.arange(len(faces)), 3)
    graph = coo_matrix(
        (np.ones(len(owner)), (owner, edge_id.ravel() + len(faces))),
        shape=(len(faces) + edge_id.max() + 1,) * 2,
    )
    _, labels = connected_components(graph, directed=False)
    return np.unique(labels[: len(faces)], return_inverse=True)[1].ravel()
