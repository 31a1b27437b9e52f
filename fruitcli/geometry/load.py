"""Loading and checking an artist's mesh: one closed, consistently oriented volume in mm.

Small defects are repaired (duplicate vertices, degenerate faces, small holes, winding,
inside-out orientation) and each repair is reported; what cannot be repaired is refused
with a GeometryError naming the file and what to change.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fruitcli.errors import GeometryError

MESH_SUFFIXES = (".stl", ".obj", ".ply")
UNIT_TO_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0}
MAX_EXTENT_MM = 5000.0
"""A mesh larger than this (after its unit) is refused: a touch skin for a soft robot is
not 5 m across, so the unit is wrong (a mm file read with --unit m took minutes)."""

MIN_EXTENT_MM = 2.0
"""A mesh read in mm and smaller than this across is refused: it is in m or cm."""
# holes with at most this many boundary edges are closed by a fan (a "small hole")
MAX_HOLE_EDGES = 64
MAX_HOLE_FRACTION = 0.1
"""A hole is closed only when it spans at most this fraction of the body's largest extent
(bounding-box diagonal of its boundary loop). A flat fan across a hole of width w on a
surface of radius R sags by w^2 / (8 R): at a tenth of a sphere's diameter that is R / 200,
0.2 mm on an 80 mm body (a tenth of the default cover). Larger holes are real openings
(a cut-off cap): the mesh is refused as open."""
CLI_UNIT_HINT = "give its unit (--unit m or --unit cm)"
SCENE_UNIT_HINT = 'set [geometry].unit = "m" (or "cm")'
# relative agreement required between trimesh's and manifold's volume
VOLUME_RTOL = 1e-3


def check_extent(verts_mm: np.ndarray, unit: str, what: str, hint: str) -> None:
    """Refuse a mesh whose size (vertices in mm, read from a file in `unit`) says the
    unit is wrong: under MIN_EXTENT_MM read as mm (it is in metres or centimetres; `hint`
    says how to give its unit), over MAX_EXTENT_MM in any unit. `what` names the mesh
    (and where it was given)."""
    extent = float(np.ptp(verts_mm, axis=0).max())
    if unit == "mm" and extent < MIN_EXTENT_MM:
        raise GeometryError(f"{what} is only {extent:.3g} mm across, so it is not in "
                            f"millimetres; {hint}")
    if extent > MAX_EXTENT_MM:
        raise GeometryError(f"{what} is {extent:.4g} mm across in {unit}, more than "
                            f"{MAX_EXTENT_MM:g} mm: is that its unit?")


def load_mesh(path, unit: str | None = None, unit_hint: str = CLI_UNIT_HINT):
    """Load `path` as one closed volume in mm. Returns (trimesh.Trimesh, repairs: list[str]).
    Unless `unit` is cm or m the mesh must be at least MIN_EXTENT_MM across (`unit_hint`
    tells how to give its unit)."""
    import trimesh

    path = Path(path)
    if not path.exists():
        raise GeometryError(f"{path}: file not found")
    if path.is_dir():
        raise GeometryError(f"{path}: is a folder (expected an STL, OBJ or PLY mesh file)")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise GeometryError(f"{path}: unknown mesh format '{path.suffix}' "
                            "(expected .stl, .obj or .ply)")
    if path.stat().st_size == 0:
        raise GeometryError(f"{path}: empty file (expected a closed triangle mesh)")
    if unit is not None and unit not in UNIT_TO_MM:
        raise GeometryError(f"{path}: unknown unit '{unit}' (expected mm, cm or m)")
    try:
        mesh = trimesh.load_mesh(path, process=False, force="mesh")
    except Exception as exc:  # noqa: BLE001 - any parser failure is a bad file
        # (a garbage binary STL makes trimesh try it as text, which may need a module
        # that is not installed: that says nothing about the file, so it is not shown)
        why = "" if isinstance(exc, ImportError) else \
            f" ({type(exc).__name__}: {(str(exc).splitlines() or [''])[0][:80]})"
        raise GeometryError(f"{path}: cannot read as a {path.suffix[1:].upper()} mesh{why}; "
                            "is it a triangle mesh file?") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise GeometryError(f"{path}: no triangles found (expected a closed triangle mesh)")
    verts = np.asarray(mesh.vertices, dtype=float)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if not np.isfinite(verts).all():
        raise GeometryError(f"{path}: vertices contain NaN or infinite coordinates")
    if faces.min() < 0 or faces.max() >= len(verts):
        raise GeometryError(f"{path}: faces refer to missing vertices")

    unit = unit or "mm"
    verts = verts * UNIT_TO_MM[unit]
    check_extent(verts, unit, f"{path}: the mesh", unit_hint)
    verts, faces, repairs = repair_arrays(verts, faces)
    if unit != "mm":
        repairs.insert(0, f"scaled from {unit} to mm (x{UNIT_TO_MM[unit]:g})")
    _check_closed(path, verts, faces)
    oriented = orient_faces(faces)
    if oriented is None:
        raise GeometryError(f"{path}: face winding cannot be made consistent "
                            "(the surface is not orientable)")
    flipped = int((oriented[:, 0] != faces[:, 0]).sum())
    if flipped:
        repairs.append(f"fixed inconsistent face winding ({flipped} faces flipped)")
    mesh = trimesh.Trimesh(verts, oriented, process=False)
    if mesh.volume < 0:
        mesh.invert()
        repairs.append("inverted inside-out orientation")
    check_manifold(path, mesh)
    return mesh, repairs


def repair_arrays(verts: np.ndarray, faces: np.ndarray):
    """Merge duplicate vertices, drop degenerate and duplicate faces, close small holes."""
    import trimesh

    repairs = []
    merged = trimesh.Trimesh(verts, faces, process=False)
    merged.merge_vertices(merge_tex=True, merge_norm=True)
    if len(merged.vertices) < len(verts):
        repairs.append(f"merged {len(verts) - len(merged.vertices)} duplicate vertices")
    verts = np.asarray(merged.vertices, dtype=float)
    faces = np.asarray(merged.faces, dtype=np.int64)
    degenerate = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) \
        | (faces[:, 0] == faces[:, 2])
    if degenerate.any():
        repairs.append(f"removed {int(degenerate.sum())} degenerate faces")
        faces = faces[~degenerate]
    sf = np.sort(faces, axis=1)
    n = int(faces.max()) + 1
    _, first = np.unique((sf[:, 0] * n + sf[:, 1]) * n + sf[:, 2], return_index=True)
    if len(first) < len(faces):
        repairs.append(f"removed {len(faces) - len(first)} duplicate faces")
        faces = faces[np.sort(first)]
    faces, filled = _fill_small_holes(verts, faces)
    if filled:
        verts = np.concatenate([verts, filled[1]])
        repairs.append(f"closed {filled[0]} small hole(s)")
    return verts, faces, repairs


def _boundary_edges(faces: np.ndarray) -> np.ndarray:
    """Directed edges (k, 2) used by exactly one face (any direction)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    counts = _edge_use(faces)
    return e[counts == 1]


def _edge_use(faces: np.ndarray) -> np.ndarray:
    """For each directed edge (3m,) in face order, how many faces use its undirected edge."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    n = int(faces.max()) + 1
    key = e.min(axis=1) * n + e.max(axis=1)
    _, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    return counts[inv]


def _fill_small_holes(verts: np.ndarray, faces: np.ndarray):
    """Close simple boundary loops of <= MAX_HOLE_EDGES edges, spanning at most
    MAX_HOLE_FRACTION of the body, by a fan to their centroid (all of them or none)."""
    edges = _boundary_edges(faces)
    if len(edges) == 0:
        return faces, None
    max_span = MAX_HOLE_FRACTION * float(np.ptp(verts, axis=0).max())
    nxt: dict[int, list[int]] = {}
    for a, b in edges.tolist():
        nxt.setdefault(a, []).append(b)
    if any(len(v) != 1 for v in nxt.values()):
        return faces, None          # pinched boundary: leave it to the closedness check
    seen: set[int] = set()
    new_faces, centres = [], []
    for start in sorted(nxt):
        if start in seen:
            continue
        loop = [start]
        seen.add(start)
        cur = nxt[start][0]
        while cur != start and cur in nxt and cur not in seen and len(loop) <= MAX_HOLE_EDGES:
            loop.append(cur)
            seen.add(cur)
            cur = nxt[cur][0]
        if cur != start or np.linalg.norm(np.ptp(verts[loop], axis=0)) > max_span:
            return faces, None      # an open or too large boundary: not a small hole
        c = len(verts) + len(centres)
        centres.append(verts[loop].mean(axis=0))
        for a, b in zip(loop, loop[1:] + loop[:1], strict=True):
            new_faces.append((b, a, c))
    return np.concatenate([faces, np.asarray(new_faces, dtype=np.int64)]), \
        (len(centres), np.asarray(centres))


def orient_faces(faces: np.ndarray) -> np.ndarray | None:
    """Faces of a closed edge-manifold mesh with winding made consistent (each
    component keeps its first face's winding), or None if the surface is not orientable.

    Without networkx (trimesh.repair.fix_winding needs it): faces are visited breadth
    first through shared edges, each flipped when it runs an edge the same way as the
    face it was reached from.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order

    m = len(faces)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    owner = np.tile(np.arange(m), 3)
    n = int(faces.max()) + 1
    key = e.min(axis=1) * n + e.max(axis=1)
    order = np.argsort(key, kind="stable")
    a, b = order[0::2], order[1::2]            # closed and manifold: each edge twice
    same = e[a, 0] == e[b, 0]                  # both faces run the edge the same way
    fa, fb = owner[a], owner[b]
    graph = coo_matrix((np.ones(len(fa)), (fa, fb)), shape=(m, m)).tocsr()
    # each face's three neighbours and whether it runs the shared edge the same way
    nbr = np.concatenate([fb, fa])
    rel = np.concatenate([same, same])
    src = np.concatenate([fa, fb])
    o = np.argsort(src, kind="stable")
    nbr, rel = nbr[o].reshape(m, 3), rel[o].reshape(m, 3)
    flip = np.zeros(m, dtype=bool)
    seen = np.zeros(m, dtype=bool)
    for root in range(m):
        if seen[root]:
            continue
        visit, pred = breadth_first_order(graph, root, directed=False)
        seen[visit] = True
        f = visit[1:]
        r = rel[f, np.argmax(nbr[f] == pred[f][:, None], axis=1)].tolist()
        fl = flip.tolist()
        for fi, pi, ri in zip(f.tolist(), pred[f].tolist(), r, strict=True):
            fl[fi] = fl[pi] ^ ri
        flip = np.asarray(fl, dtype=bool)
    if (flip[fa] ^ flip[fb] ^ same).any():
        return None
    out = faces.copy()
    out[flip] = out[flip][:, ::-1]
    return out


def component_count(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Connected-component label per face (faces joined through shared vertices)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    rows = np.repeat(np.arange(len(faces)), 3)
    graph = coo_matrix((np.ones(len(rows)), (rows, faces.ravel() + len(faces))),
                       shape=(len(faces) + n_vertices,) * 2)
    _, labels = connected_components(graph, directed=False)
    return labels[: len(faces)]


def _check_closed(path: Path, verts: np.ndarray, faces: np.ndarray) -> None:
    open_edges = len(_boundary_edges(faces))
    if open_edges:
        raise GeometryError(f"{path}: the mesh is not closed ({open_edges} open edges after "
                            "repair); close its holes in a modeller first")
    counts = _edge_use(faces)
    if (counts > 2).any():
        raise GeometryError(f"{path}: {int((counts > 2).sum() // 3)} edges are shared by more than "
                            "two faces (non-manifold); repair the mesh first")
    labels = component_count(faces, len(verts))
    bodies = len(np.unique(labels))
    if bodies > 1:
        raise GeometryError(f"{path}: the mesh has {bodies} separate bodies (expected one "
                            "closed volume); merge or delete the extra bodies")


def to_manifold(vertices: np.ndarray, faces: np.ndarray):
    """A manifold3d.Manifold from arrays (vertices float64 mm, faces int)."""
    import manifold3d

    mesh = manifold3d.Mesh(np.ascontiguousarray(vertices, dtype=np.float32),
                           np.ascontiguousarray(faces, dtype=np.uint32))
    return manifold3d.Manifold(mesh)


def check_manifold(path, mesh) -> None:
    """Refuse what manifold3d cannot use: bad status, empty, or a volume it disagrees on."""
    import manifold3d

    m = to_manifold(mesh.vertices, mesh.faces)
    if m.status() != manifold3d.Error.NoError or m.is_empty():
        raise GeometryError(f"{path}: manifold3d rejects the mesh ({m.status().name}); "
                            "it must be one closed, non-self-touching surface")
    vol, ref = m.volume(), float(mesh.volume)
    if vol <= 0 or abs(vol - ref) > VOLUME_RTOL * abs(ref) + 1e-6:
        raise GeometryError(f"{path}: inconsistent volume ({vol:.6g} vs {ref:.6g} mm^3); "
                            "the surface may overlap itself")
