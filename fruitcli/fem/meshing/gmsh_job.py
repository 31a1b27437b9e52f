"""Child process that runs gmsh (``python -m fruitcli.fem.meshing.gmsh_job JOB.npz OUT_DIR``).

gmsh can ignore polite signals for a long time, so the parent (`fruitcli.fem.meshing.tetra`)
runs this module in its own process group and kills it after the time limit; the child
ends with its parent (`child_process.follow_parent`), so a killed `fruit run` leaves no gmsh behind.

JOB.npz holds shells in order (the outer boundary first, then one per chamber), each
either a triangle surface (`s{i}_vertices`, `s{i}_faces`, mm) or an analytic shape
triangulated here with OpenCASCADE (`s{i}_box` [x0,y0,z0,dx,dy,dz] or `s{i}_ellipsoid`
[cx,cy,cz,a,b,c]) at the size `s{i}_size` and kept. A surface with `s{i}_bottom` (per
face, True for the bottom patch) is cut into two disk patches that gmsh reparametrizes
and remeshes; without it the surface is kept as is. `base` says the outer bottom patch
is the base. Sizes: `size_mm` (MeshSizeMax), `curvature_min_mm` (MeshSizeMin, the floor
of the curvature refinement, `curvature_n` elements per 2 pi), a Box field per chamber
(`s{i}_refine_box` [xmin,ymin,zmin,xmax,ymax,zmax] at `s{i}_size`) and a Ball field of
radius `taxel_radius_mm` at `min_size_mm` around each of `taxels` (t, 3). Writes
OUT_DIR/raw.npz (nodes, tets, triangles per shell `tris{i}`, `base_tris`, minSICN and
gamma per tet) and OUT_DIR/mesh.msh.
"""

from __future__ import annotations

import sys
from pathlib import Path
from types import ModuleType

import numpy as np

from fruitcli.interrupts import ignore_sigpipe


def _occ_surface(gmsh: ModuleType, spec_kind: str, values: np.ndarray, size: float):
    """Triangulate an analytic shape's surface; returns (vertices (v,3), faces (f,3))."""
    gmsh.model.add(f"shape_{spec_kind}")
    occ = gmsh.model.occ
    if spec_kind == "box":
        occ.addBox(*values)
    else:
        c, r = values[:3], values[3:]
        tag = occ.addSphere(c[0], c[1], c[2], 1.0)
        occ.dilate([(3, tag)], c[0], c[1], c[2], r[0], r[1], r[2])
    occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.5 * size)
    gmsh.model.mesh.generate(2)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    _, elem_nodes = gmsh.model.mesh.getElementsByType(2)
    index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    faces = index[elem_nodes.astype(np.int64)].reshape(-1, 3)
    used, faces = np.unique(faces, return_inverse=True)
    vertices = coords.reshape(-1, 3)[used]
    gmsh.model.remove()
    return vertices, faces.reshape(-1, 3)


class _Tags:
    """Running tags of gmsh entities and nodes (one model, one numbering)."""

    def __init__(self):
        self.next = {0: 1, 1: 1, 2: 1}
        self.node = 1

    def entity(self, dim: int) -> int:
        self.next[dim] += 1
        return self.next[dim] - 1

    def nodes(self, n: int) -> np.ndarray:
        self.node += n
        return np.arange(self.node - n, self.node)


def _add_kept(gmsh: ModuleType, tags: _Tags, v: np.ndarray, f: np.ndarray) -> list[int]:
    """One discrete surface meshed as given (no parametrization: gmsh keeps it)."""
    s = tags.entity(2)
    gmsh.model.addDiscreteEntity(2, s)
    node = tags.nodes(len(v))
    gmsh.model.mesh.addNodes(2, s, node, np.asarray(v, float).ravel())
    gmsh.model.mesh.addElementsByType(s, 2, [], node[np.asarray(f)].ravel())
    return [s]


def _add_split(gmsh: ModuleType, tags: _Tags, v: np.ndarray, f: np.ndarray, bottom: np.ndarray):
    """A closed shell as two discrete disk patches (top, bottom) bounded by two curves
    through the min-x and max-x vertices of their shared loop; returns the surface tags
    and the dimTags that `createGeometry` must parametrize."""
    from fruitcli.fem.meshing.patches import boundary_loops, split_loop

    f = np.asarray(f, np.int64)
    (loop,) = boundary_loops(f[bottom])
    paths = split_loop(loop, v)
    node = tags.nodes(len(v))
    owner = np.zeros(len(v), np.int64)  # 0 free, 1 on a curve or point
    pts = []
    for i in (paths[0][0], paths[0][-1]):
        p = tags.entity(0)
        gmsh.model.addDiscreteEntity(0, p)
        gmsh.model.mesh.addNodes(0, p, [node[i]], v[i])
        owner[i] = 1
        pts.append(p)
    curves = []
    for path in paths:
        c = tags.entity(1)
        gmsh.model.addDiscreteEntity(1, c, pts)
        inner = path[1:-1]
        gmsh.model.mesh.addNodes(1, c, node[inner], v[inner].ravel())
        owner[inner] = 1
        lines = np.stack([path[:-1], path[1:]], axis=1)
        gmsh.model.mesh.addElementsByType(c, 1, [], node[lines].ravel())
        curves.append(c)
    surfaces = []
    for part in (~bottom, bottom):
        s = tags.entity(2)
        gmsh.model.addDiscreteEntity(2, s, curves)
        inner = np.unique(f[part])
        inner = inner[owner[inner] == 0]
        gmsh.model.mesh.addNodes(2, s, node[inner], v[inner].ravel())
        gmsh.model.mesh.addElementsByType(s, 2, [], node[f[part]].ravel())
        surfaces.append(s)
    return surfaces, [(1, c) for c in curves] + [(2, s) for s in surfaces]


def _size_field(gmsh: ModuleType, job: dict, size: float, min_size: float) -> None:
    """Background size: each chamber's wall size inside its box (growing to size over
    one size outside), min_size within the taxel radius of each taxel."""
    fields = []

    def add(kind: str, values: dict) -> None:
        f = gmsh.model.mesh.field.add(kind)
        for key, val in values.items():
            gmsh.model.mesh.field.setNumber(f, key, float(val))
        fields.append(f)

    for i in range(1, int(job["n_shells"])):
        lo_hi = job[f"s{i}_refine_box"]
        add(
            "Box",
            {
                "XMin": lo_hi[0],
                "YMin": lo_hi[1],
                "ZMin": lo_hi[2],
                "XMax": lo_hi[3],
                "YMax": lo_hi[4],
                "ZMax": lo_hi[5],
                "Thickness": size,
                "VIn": float(job[f"s{i}_size"]),
                "VOut": size,
            },
        )
    if "taxels" in job:
        radius = float(job["taxel_radius_mm"])
        for x, y, z in np.asarray(job["taxels"], float).reshape(-1, 3):
            add(
                "Ball",
                {
                    "XCenter": x,
                    "YCenter": y,
                    "ZCenter": z,
                    "Radius": radius,
                    "Thickness": size,
                    "VIn": min_size,
                    "VOut": size,
                },
            )
    if fields:
        m = gmsh.model.mesh.field.add("Min")
        gmsh.model.mesh.field.setNumbers(m, "FieldsList", fields)
        gmsh.model.mesh.field.setAsBackgroundMesh(m)


def mesh_job(job: dict, out_dir: Path) -> None:
    import gmsh

    gmsh.initialize(["fruit-tetra"], readConfigFiles=False)
    ignore_sigpipe()  # gmsh leaves SIGPIPE at its default
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        size, min_size = float(job["size_mm"]), float(job["min_size_mm"])
        shells = []
        for i in range(int(job["n_shells"])):
            if f"s{i}_faces" in job:
                shells.append((job[f"s{i}_vertices"], job[f"s{i}_faces"], job.get(f"s{i}_bottom")))
            else:
                kind = "box" if f"s{i}_box" in job else "ellipsoid"
                shells.append(
                    (*_occ_surface(gmsh, kind, job[f"s{i}_{kind}"], float(job[f"s{i}_size"])), None)
                )
        gmsh.model.add("fruit")
        tags, shell_surfaces, to_param, base = _Tags(), [], [], []
        for i, (v, f, bottom) in enumerate(shells):
            if bottom is None:
                shell_surfaces.append(_add_kept(gmsh, tags, v, f))
            else:
                surf, dim_tags = _add_split(
                    gmsh, tags, np.asarray(v, float), f, np.asarray(bottom, bool)
                )
                shell_surfaces.append(surf)
                to_param += dim_tags
                if i == 0 and bool(job.get("base", False)):
                    base.append(surf[1])
        if to_param:
            gmsh.model.mesh.createGeometry(to_param)
        loops = [gmsh.model.geo.addSurfaceLoop(surf) for surf in shell_surfaces]
        gmsh.model.geo.addVolume(loops)
        gmsh.model.geo.synchronize()
        gmsh.model.addPhysicalGroup(3, [1], name="silicone")
        gmsh.model.addPhysicalGroup(
            2, [s for s in shell_surfaces[0] if s not in base], name="outer"
        )
        if base:
            gmsh.model.addPhysicalGroup(2, base, name="base")
        for i in range(1, len(shells)):
            gmsh.model.addPhysicalGroup(2, shell_surfaces[i], name=f"chamber{i - 1}")
        _size_field(gmsh, job, size, min_size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.MeshSizeMin", float(job["curvature_min_mm"]))
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", float(job["curvature_n"]))
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.optimize("Netgen")
        tags_, coords, _ = gmsh.model.mesh.getNodes()
        index = np.zeros(int(tags_.max()) + 1, dtype=np.int64)
        index[tags_.astype(np.int64)] = np.arange(len(tags_))
        tet_tags, tet_nodes = gmsh.model.mesh.getElementsByType(4)
        out = {
            "nodes": coords.reshape(-1, 3),
            "tets": index[tet_nodes.astype(np.int64)].reshape(-1, 4),
            "sicn": np.asarray(gmsh.model.mesh.getElementQualities(tet_tags, "minSICN")),
            "gamma": np.asarray(gmsh.model.mesh.getElementQualities(tet_tags, "gamma")),
        }

        def tris(surfs: list[int]) -> np.ndarray:
            got = [gmsh.model.mesh.getElementsByType(2, s)[1] for s in surfs]
            return index[np.concatenate(got).astype(np.int64)].reshape(-1, 3)

        for i, surf in enumerate(shell_surfaces):
            out[f"tris{i}"] = tris(surf)
        out["base_tris"] = tris(base) if base else np.zeros((0, 3), np.int64)
        gmsh.option.setNumber("Mesh.SaveAll", 0)
        gmsh.write(str(out_dir / "mesh.msh"))
        np.savez(out_dir / "raw.npz", **out)
    finally:
        gmsh.finalize()


def main(argv: list[str]) -> int:
    from fruitcli.fem.meshing.child_process import follow_parent

    follow_parent()
    job_path, out_dir = Path(argv[0]), Path(argv[1])
    with np.load(job_path, allow_pickle=False) as data:
        job = {k: data[k] for k in data.files}
    try:
        mesh_job(job, out_dir)
    except Exception as exc:  # reported to the parent on stderr, one line
        print(
            f"gmsh: {str(exc).strip().splitlines()[-1] if str(exc).strip() else exc!r}",
            file=sys.stderr,
        )
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
