"""Tetrahedralize a body and its chambers with gmsh in a killable child process.

The boundary is handed to gmsh by hand as discrete surfaces. A triangle surface (the
solid, or a chamber file) is cut into two disk patches (`fruitcli.fem.meshing.patches`: the
flat base and the rest when the solid stands on one) that gmsh reparametrizes and
remeshes at the target size, so `[mesh].size_mm` sets the element size whatever the
input triangles are. Analytic chambers (ellipsoids) and the flat pad (box) are
triangulated by OpenCASCADE at their size and kept. One volume with the chambers as
holes is then meshed (Delaunay) and Netgen-optimized. Sizes in mm:

- the outer surface and the volume at `size_mm`, refined by curvature (8 elements per
  2 pi radius) down to `CURVATURE_MIN_FRACTION * size_mm` (or `min_size_mm` if smaller);
- each chamber wall, and its bounding box padded by that size, at `min_size_mm` but
  never coarser than `CLEARANCE_FACTOR` times its clearance to the outer surface and
  the other chambers (a coarse wall would cross them);
- `min_size_mm` within `TAXEL_RADIUS_MM` of each taxel, growing to `size_mm` over one
  `size_mm` further out.

Surface tags (`surface_tri_tag` of mesh.npz, outer surface only): 0 other outer
surface, 1 base (the flat bottom the solid stands on), 2 taxels' region (within
`TAXEL_RADIUS_MM` of a taxel; the base wins where both apply). The child is killed
after `time_limit_s` seconds. Same input, same mesh (no randomness in any step).

Fallback chain (`fallback_plan`): when gmsh refuses the boundary it was given (a PLC
error: remeshed facets that cross or overlap), the mesh is tried again at `size_mm *
FALLBACK_SIZE_FACTOR`, then at `size_mm` with the surfaces kept as the input triangles
(no remeshing: the size then acts on the volume only). Every attempt is logged as a
warning, passed to `progress` when given, and listed in the mesh's `attempts` (a JSON
string, copied to quality.json); when all fail, the one-line error names the input
and what to change. Other failures (timeout, an open surface) are not retried.
"""

from __future__ import annotations

import json
import logging
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from fruitcli.errors import MeshError
from fruitcli.fem.meshing.patches import split_bottom_top
from fruitcli.fem.meshing.quality import min_dihedral_deg
from fruitcli.fem.meshing.topology import boundary_faces

BASE_NORMAL_COS = 0.999
"""A boundary face of an analytic box whose outward normal has n_z below -this, on the
lowest plane, is base (surface solids get their base from the patch split)."""

CURVATURE_ELEMENTS = 8.0
"""gmsh's Mesh.MeshSizeFromCurvature: elements per 2 pi radius of curvature."""

CURVATURE_MIN_FRACTION = 0.5
"""Curvature refines the outer surface down to this fraction of size_mm at most."""

TAXEL_RADIUS_MM = 3.0
"""Surface triangles within this distance of a taxel are its region (tag 2), meshed at
min_size_mm."""

CLEARANCE_SAMPLE_MM = 0.5
"""Spacing of the points sampled on the outer surface to measure chamber clearance."""

CLEARANCE_FACTOR = 2.0
"""A chamber wall is meshed no coarser than this many times its clearance to the outer
surface or another chamber (a chord that long sags well under the gap on the flat
sides of the chambers; at 3x the default fruit's facets crossed at size 8)."""

TAG_OUTER, TAG_BASE, TAG_TAXEL = 0, 1, 2

FALLBACK_SIZE_FACTOR = 0.97
"""Second attempt after a PLC failure: this fraction of size_mm (moves every node of the
remeshed curves and surfaces, so the crossing facets are not built again)."""

RETRY_MARKERS = ("PLC Error", "intersect", "overlap")
"""gmsh failures (in its message) that the fallback chain retries: the boundary handed to
the 3D mesher crosses itself."""

log = logging.getLogger(__name__)


def surface_samples(vertices: np.ndarray, faces: np.ndarray, step: float) -> np.ndarray:
    """(p, 3) points on every triangle at most about `step` apart (barycentric grids)."""
    tri = np.asarray(vertices, float)[np.asarray(faces)]
    edge = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    k = np.maximum(1, np.ceil(edge / step)).astype(np.int64)
    out = [tri.reshape(-1, 3)]
    for kk in np.unique(k[k > 1]):
        i, j = np.meshgrid(np.arange(kk + 1), np.arange(kk + 1), indexing="ij")
        keep = i + j <= kk
        w = np.stack([i[keep], j[keep], kk - i[keep] - j[keep]], 1) / kk
        out.append(np.einsum("pk,mkd->mpd", w, tri[k == kk]).reshape(-1, 3))
    return np.concatenate(out)


def chamber_sizes(shells: list[dict], min_size_mm: float) -> list[float]:
    """Wall size per chamber: min_size_mm, or its clearance to the outer surface and to
    the other chambers when that is smaller (only triangles closer than min_size_mm to
    the chamber's bounding box are sampled)."""
    from scipy.spatial import cKDTree

    sizes = []
    for k, ch in enumerate(shells[1:]):
        pts = np.asarray(ch["vertices"], float)
        lo, hi = pts.min(axis=0) - min_size_mm, pts.max(axis=0) + min_size_mm
        gap = min_size_mm
        for j, sh in enumerate(shells):
            if j == k + 1:
                continue
            tri = np.asarray(sh["vertices"], float)[np.asarray(sh["faces"])]
            near = np.all((tri.max(axis=1) >= lo) & (tri.min(axis=1) <= hi), axis=1)
            if near.any():
                v, f = tri[near].reshape(-1, 3), np.arange(3 * near.sum()).reshape(-1, 3)
                samples = surface_samples(v, f, CLEARANCE_SAMPLE_MM)
                gap = min(gap, float(cKDTree(samples).query(pts)[0].min()))
        sizes.append(min(min_size_mm, CLEARANCE_FACTOR * max(gap, CLEARANCE_SAMPLE_MM)))
    return sizes


def fallback_plan(size_mm: float) -> list[tuple[float, bool]]:
    """(size_mm, remesh the surfaces) of each attempt, in order."""
    return [(size_mm, True), (size_mm * FALLBACK_SIZE_FACTOR, True), (size_mm, False)]


def build_job(
    shells: list[dict],
    size_mm: float,
    min_size_mm: float,
    taxels_xyz: np.ndarray | None = None,
    remesh: bool = True,
) -> dict:
    """The arrays handed to the gmsh child (see `fruitcli.fem.meshing.gmsh_job`). With
    remesh=False the triangle surfaces are kept as they are (no patch split)."""
    wall = chamber_sizes(shells, min_size_mm)
    # gmsh clamps every size to MeshSizeMin: chamber files remeshed at their wall size
    # need it that low; analytic chambers are triangulated apart and kept
    remeshed_walls = [w for w, sh in zip(wall, shells[1:], strict=True) if sh["kind"] == "surface"]
    job = {
        "n_shells": np.array(len(shells)),
        "size_mm": np.array(size_mm),
        "min_size_mm": np.array(min_size_mm),
        "curvature_min_mm": np.array(
            min([min_size_mm, CURVATURE_MIN_FRACTION * size_mm, *remeshed_walls])
        ),
        "curvature_n": np.array(CURVATURE_ELEMENTS),
        "base": np.array(False),
    }
    for i, sh in enumerate(shells):
        h = size_mm if i == 0 else wall[i - 1]
        if sh["kind"] == "surface":
            job[f"s{i}_vertices"], job[f"s{i}_faces"] = sh["vertices"], sh["faces"]
            split = split_bottom_top(sh["vertices"], sh["faces"]) if remesh else None
            if split is not None:
                job[f"s{i}_bottom"] = split[0]
                if i == 0:
                    job["base"] = np.array(split[1])
        else:
            job[f"s{i}_{sh['kind']}"] = sh["params"]
        job[f"s{i}_size"] = np.array(h)
        if i > 0:
            v = np.asarray(sh["vertices"], float)
            pad = wall[i - 1]
            job[f"s{i}_refine_box"] = np.concatenate([v.min(axis=0) - pad, v.max(axis=0) + pad])
    if taxels_xyz is not None and len(taxels_xyz) and min_size_mm < size_mm:
        job["taxels"] = np.asarray(taxels_xyz, float).reshape(-1, 3)
        job["taxel_radius_mm"] = np.array(TAXEL_RADIUS_MM)
    return job


def run_gmsh(
    shells: list[dict],
    size_mm: float,
    min_size_mm: float,
    time_limit_s: float,
    label: str,
    work_dir: Path | None = None,
    taxels_xyz: np.ndarray | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict:
    """Mesh the outer shell (first) with the chamber shells as holes, through the
    fallback chain (module docstring). Returns gmsh's raw arrays, the .msh text and
    `attempts` (JSON list of {size_mm, surfaces, result}). MeshError names `label` on
    failure or timeout."""
    attempts, plan = [], fallback_plan(size_mm)
    for n, (size, remesh) in enumerate(plan):
        surfaces = "remeshed" if remesh else "kept as input"
        try:
            raw = _run_once(
                build_job(shells, size, min(min_size_mm, size), taxels_xyz, remesh),
                time_limit_s,
                label,
                work_dir,
            )
        except MeshError as exc:
            reason = str(exc).removeprefix(f"{label}: ")
            if not any(m in reason for m in RETRY_MARKERS):
                if reason.startswith("tetrahedralization failed"):
                    raise MeshError(
                        f"{exc}; check that the surfaces are closed and apart, "
                        f"or change [mesh].size_mm"
                    ) from None
                raise
            attempts.append({"size_mm": size, "surfaces": surfaces, "result": reason})
            if n + 1 < len(plan):
                msg = (
                    f"tetra: attempt {n + 1} failed ({reason}); retrying at size "
                    f"{plan[n + 1][0]:g} mm with the surfaces "
                    f"{'remeshed' if plan[n + 1][1] else 'kept as input'}"
                )
                log.warning(msg)
                if progress is not None:
                    progress(msg)
            continue
        attempts.append({"size_mm": size, "surfaces": surfaces, "result": "ok"})
        raw["attempts"] = json.dumps(attempts)
        return raw
    raise MeshError(
        f"{label}: tetrahedralization failed in all {len(plan)} attempts (size_mm "
        f"{size_mm:g} and {size_mm * FALLBACK_SIZE_FACTOR:g} remeshed, {size_mm:g} with the "
        f"input triangles kept; last: {attempts[-1]['result']}); change [mesh].size_mm or "
        f"repair {label} (facets that cross or touch)"
    )


def _run_once(job: dict, time_limit_s: float, label: str, work_dir: Path | None) -> dict:
    """One gmsh child on `job`: its raw arrays and the .msh text."""
    from fruitcli.fem.meshing.child_process import last_error_line, run_module
    from fruitcli.fsutil import owned_prefix, sweep_orphans

    sweep_orphans(Path(work_dir or tempfile.gettempdir()), "fruit-gmsh-")
    with tempfile.TemporaryDirectory(prefix=owned_prefix("fruit-gmsh-"), dir=work_dir) as name:
        tmp = Path(name)
        np.savez(tmp / "job.npz", **job)
        try:
            code, err = run_module(
                "fruitcli.fem.meshing.gmsh_job", [str(tmp / "job.npz"), str(tmp)], time_limit_s
            )
        except TimeoutError:
            raise MeshError(
                f"{label}: gmsh did not finish within [mesh].time_limit_s = "
                f"{time_limit_s:g} s (killed); try a larger size_mm"
            ) from None
        if code != 0 or not (tmp / "raw.npz").exists():
            raise MeshError(f"{label}: tetrahedralization failed: {last_error_line(err, code)}")
        with np.load(tmp / "raw.npz", allow_pickle=False) as data:
            raw = {k: data[k] for k in data.files}
        raw["msh_text"] = (tmp / "mesh.msh").read_bytes()
    if len(raw["tets"]) == 0:
        raise MeshError(f"{label}: gmsh produced no tetrahedra (is the surface closed?)")
    return raw


def _match_faces(faces: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """Rows of `faces` (oriented) whose node sets appear in `wanted` (any order)."""
    a = np.sort(faces, axis=1)
    b = np.sort(wanted, axis=1)
    n = int(max(a.max(), b.max())) + 1
    ka = (a[:, 0] * n + a[:, 1]) * n + a[:, 2]
    kb = (b[:, 0] * n + b[:, 1]) * n + b[:, 2]
    return faces[np.isin(ka, kb)]


def surface_tags(
    nodes: np.ndarray, outer: np.ndarray, base: np.ndarray, taxels_xyz: np.ndarray | None
) -> np.ndarray:
    """(f,) int8 tag per outer triangle (see the module docstring): base where `base`,
    else taxel region where a corner or the centroid lies within TAXEL_RADIUS_MM of a
    taxel (and the triangle nearest each taxel), else 0."""
    from scipy.spatial import cKDTree

    tag = np.full(len(outer), TAG_OUTER, np.int8)
    if taxels_xyz is not None and len(taxels_xyz):
        taxels = np.asarray(taxels_xyz, float).reshape(-1, 3)
        tri = nodes[outer]
        pts = np.concatenate([tri, tri.mean(axis=1, keepdims=True)], axis=1)
        d = cKDTree(taxels).query(pts.reshape(-1, 3))[0].reshape(len(outer), 4)
        near = d.min(axis=1) <= TAXEL_RADIUS_MM
        near[cKDTree(tri.mean(axis=1)).query(taxels)[1]] = True
        tag[near] = TAG_TAXEL
    tag[base] = TAG_BASE
    return tag


def assemble_mesh(
    raw: dict, names: list[str], size_mm: float, taxels_xyz: np.ndarray | None = None
) -> dict:
    """Arrays of mesh.npz from gmsh's output: nodes, tets (positive), outer surface
    (outward) with its tags, chamber triangles (normals out of the cavity)."""
    nodes, tets = raw["nodes"], raw["tets"].astype(np.int64)
    p = nodes[tets]
    vol = np.einsum("mi,mi->m", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
    tets[vol < 0] = tets[vol < 0][:, [0, 2, 1, 3]]
    used = np.unique(tets)
    remap = np.full(len(nodes), -1, np.int64)
    remap[used] = np.arange(len(used))
    nodes, tets = nodes[used], remap[tets]
    bfaces = boundary_faces(nodes, tets)
    outer = _match_faces(bfaces, remap[raw["tris0"]])
    chamber_tris, owner = [], []
    for k in range(len(names)):
        tri = _match_faces(bfaces, remap[raw[f"tris{k + 1}"]])[:, [0, 2, 1]]
        chamber_tris.append(tri)
        owner.append(np.full(len(tri), k))
    base_tris = raw.get("base_tris", np.zeros((0, 3), np.int64))
    if len(base_tris):
        key = np.sort(outer, axis=1)
        base = np.isin(
            key @ np.array([len(nodes) ** 2, len(nodes), 1]),
            np.sort(remap[base_tris], axis=1) @ np.array([len(nodes) ** 2, len(nodes), 1]),
        )
    else:
        normals = np.cross(
            nodes[outer[:, 1]] - nodes[outer[:, 0]], nodes[outer[:, 2]] - nodes[outer[:, 0]]
        )
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        zmin = nodes[:, 2].min()
        low = np.all(nodes[outer][:, :, 2] < zmin + 1e-6 * max(size_mm, 1.0), axis=1)
        base = low & (normals[:, 2] < -BASE_NORMAL_COS)
    return {
        "nodes": nodes,
        "tets": tets,
        "surface_tris": outer,
        "surface_tri_tag": surface_tags(nodes, outer, base, taxels_xyz),
        "chamber_names": np.array(names, dtype=str),
        "chamber_tris": (
            np.concatenate(chamber_tris) if chamber_tris else np.zeros((0, 3), np.int64)
        ),
        "chamber_tri_owner": (np.concatenate(owner) if owner else np.zeros(0, np.int64)),
        "sicn": raw["sicn"],
        "gamma": raw["gamma"],
        "attempts": np.array(raw.get("attempts", "[]")),
    }


def quality_report(mesh: dict, min_quality: float) -> dict:
    """Quality figures of a mesh (gmsh's minSICN and gamma, dihedral angles in degrees)."""
    sicn, gamma = mesh["sicn"], mesh["gamma"]
    dihedral = min_dihedral_deg(mesh["nodes"], mesh["tets"])
    return {
        "n_nodes": int(len(mesh["nodes"])),
        "n_tets": int(len(mesh["tets"])),
        "sicn_min": float(sicn.min()),
        "sicn_mean": float(sicn.mean()),
        "gamma_min": float(gamma.min()),
        "gamma_mean": float(gamma.mean()),
        "min_dihedral_deg": float(dihedral.min()),
        "poor_tets": int(np.sum(sicn < min_quality)),
        "min_quality": float(min_quality),
        "attempts": json.loads(str(mesh.get("attempts", "[]"))),
    }
