"""Child process that runs gmsh (``python -m fruitcli.fem.gmsh_job JOB.npz OUT_DIR``).

gmsh can ignore polite signals for a long time, so the parent (`fruitcli.fem.tetra`)
runs this module in its own process group and kills it after the time limit.

JOB.npz holds shells in order (the outer boundary first, then one per chamber), each
either a triangle surface (`s{i}_vertices`, `s{i}_faces`, mm) kept as is, or an
analytic shape meshed here with OpenCASCADE (`s{i}_box` [x0,y0,z0,dx,dy,dz] or
`s{i}_ellipsoid` [cx,cy,cz,a,b,c]) at the size `s{i}_size`. Writes OUT_DIR/raw.npz
(nodes, tets, per-shell triangles, minSICN and gamma per tet) and OUT_DIR/mesh.msh.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np


def _occ_surface(gmsh, spec_kind: str, values: np.ndarray, size: float):
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


def mesh_job(job: dict, out_dir: Path) -> None:
    import gmsh

    gmsh.initialize(["fruit-tetra"], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        shells = []
        for i in range(int(job["n_shells"])):
            if f"s{i}_faces" in job:
                shells.append((job[f"s{i}_vertices"], job[f"s{i}_faces"]))
            else:
                kind = "box" if f"s{i}_box" in job else "ellipsoid"
                shells.append(_occ_surface(gmsh, kind, job[f"s{i}_{kind}"],
                                           float(job[f"s{i}_size"])))
        gmsh.model.add("fruit")
        offset, loops = 0, []
        for i, (v, f) in enumerate(shells):
            tag = i + 1
            gmsh.model.addDiscreteEntity(2, tag)
            gmsh.model.mesh.addNodes(2, tag, np.arange(offset + 1, offset + len(v) + 1),
                                     np.asarray(v, float).ravel())
            gmsh.model.mesh.addElementsByType(tag, 2, [], (np.asarray(f) + offset + 1).ravel())
            offset += len(v)
            loops.append(gmsh.model.geo.addSurfaceLoop([tag]))
        gmsh.model.geo.addVolume(loops)
        gmsh.model.geo.synchronize()
        gmsh.model.addPhysicalGroup(3, [1], name="silicone")
        gmsh.model.addPhysicalGroup(2, [1], name="outer")
        for i in range(1, len(shells)):
            gmsh.model.addPhysicalGroup(2, [i + 1], name=f"chamber{i - 1}")
        gmsh.option.setNumber("Mesh.MeshSizeMax", float(job["size_mm"]))
        gmsh.option.setNumber("Mesh.MeshSizeMin", float(job["min_size_mm"]))
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.optimize("Netgen")
        tags, coords, _ = gmsh.model.mesh.getNodes()
        index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
        index[tags.astype(np.int64)] = np.arange(len(tags))
        tet_tags, tet_nodes = gmsh.model.mesh.getElementsByType(4)
        out = {"nodes": coords.reshape(-1, 3),
               "tets": index[tet_nodes.astype(np.int64)].reshape(-1, 4),
               "sicn": np.asarray(gmsh.model.mesh.getElementQualities(tet_tags, "minSICN")),
               "gamma": np.asarray(gmsh.model.mesh.getElementQualities(tet_tags, "gamma"))}
        for i in range(len(shells)):
            _, tri_nodes = gmsh.model.mesh.getElementsByType(2, i + 1)
            out[f"tris{i}"] = index[tri_nodes.astype(np.int64)].reshape(-1, 3)
        gmsh.option.setNumber("Mesh.SaveAll", 0)
        gmsh.write(str(out_dir / "mesh.msh"))
        np.savez(out_dir / "raw.npz", **out)
    finally:
        gmsh.finalize()


def main(argv: list[str]) -> int:
    job_path, out_dir = Path(argv[0]), Path(argv[1])
    with np.load(job_path, allow_pickle=False) as data:
        job = {k: data[k] for k in data.files}
    try:
        mesh_job(job, out_dir)
    except Exception as exc:  # reported to the parent on stderr, one line
        print(f"gmsh: {str(exc).strip().splitlines()[-1] if str(exc).strip() else exc!r}",
              file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
