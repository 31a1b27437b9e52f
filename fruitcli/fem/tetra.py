"""Tetrahedralize a body and its chambers with gmsh in a killable child process.

The boundary is handed to gmsh as discrete surfaces (the solid's own triangles, or a
box/ellipsoid triangulated by OpenCASCADE at the target size), one surface loop per
shell and one volume with the chambers as holes, then meshed and Netgen-optimized.
Sizes in mm; the child is killed after `time_limit_s` seconds.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from fruitcli.errors import MeshError
from fruitcli.fem.mesh_topology import boundary_faces
from fruitcli.fem.quality import min_dihedral_deg

BASE_NORMAL_COS = 0.999
"""A boundary face whose outward normal has n_z below -this, on the lowest plane, is base."""


def run_gmsh(shells: list[dict], size_mm: float, min_size_mm: float, time_limit_s: float,
             label: str, work_dir: Path | None = None) -> dict:
    """Mesh the outer shell (first) with the chamber shells as holes. Returns gmsh's raw
    arrays and the .msh text path. MeshError names `label` on failure or timeout."""
    with tempfile.TemporaryDirectory(prefix="fruit-gmsh-", dir=work_dir) as tmp:
        tmp = Path(tmp)
        job = {"n_shells": np.array(len(shells)), "size_mm": np.array(size_mm),
               "min_size_mm": np.array(min_size_mm)}
        for i, sh in enumerate(shells):
            if sh["kind"] == "surface":
                job[f"s{i}_vertices"], job[f"s{i}_faces"] = sh["vertices"], sh["faces"]
            else:
                job[f"s{i}_{sh['kind']}"] = sh["params"]
                job[f"s{i}_size"] = np.array(size_mm if i == 0 else min_size_mm)
        np.savez(tmp / "job.npz", **job)
        cmd = [sys.executable, "-m", "fruitcli.fem.gmsh_job", str(tmp / "job.npz"), str(tmp)]
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [str(Path(__file__).resolve().parents[2]), os.environ.get("PYTHONPATH", "")]))
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                start_new_session=True, env=env, text=True)
        try:
            _, err = proc.communicate(timeout=time_limit_s)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            raise MeshError(f"{label}: gmsh did not finish within [mesh].time_limit_s = "
                            f"{time_limit_s:g} s (killed); try a larger size_mm") from None
        if proc.returncode != 0 or not (tmp / "raw.npz").exists():
            lines = [ln for ln in err.strip().splitlines() if ln.strip()]
            msg = lines[-1] if lines else f"exit code {proc.returncode}"
            raise MeshError(f"{label}: tetrahedralization failed: {msg}")
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


def assemble_mesh(raw: dict, names: list[str], size_mm: float) -> dict:
    """Arrays of mesh.npz from gmsh's output: nodes, tets (positive), outer surface
    (outward) with base tag, chamber triangles (normals out of the cavity)."""
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
    normals = np.cross(nodes[outer[:, 1]] - nodes[outer[:, 0]],
                       nodes[outer[:, 2]] - nodes[outer[:, 0]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    zmin = nodes[:, 2].min()
    low = np.all(nodes[outer][:, :, 2] < zmin + 1e-6 * max(size_mm, 1.0), axis=1)
    base = low & (normals[:, 2] < -BASE_NORMAL_COS)
    return {
        "nodes": nodes, "tets": tets, "surface_tris": outer,
        "surface_tri_tag": base.astype(np.int8),  # 0 outer, 1 base
        "chamber_names": np.array(names, dtype=str),
        "chamber_tris": (np.concatenate(chamber_tris) if chamber_tris
                         else np.zeros((0, 3), np.int64)),
        "chamber_tri_owner": (np.concatenate(owner) if owner else np.zeros(0, np.int64)),
        "sicn": raw["sicn"],
        "gamma": raw["gamma"],
    }


def quality_report(mesh: dict, min_quality: float) -> dict:
    """Quality figures of a mesh (gmsh's minSICN and gamma, dihedral angles in degrees)."""
    sicn, gamma = mesh["sicn"], mesh["gamma"]
    dihedral = min_dihedral_deg(mesh["nodes"], mesh["tets"])
    return {"n_nodes": int(len(mesh["nodes"])), "n_tets": int(len(mesh["tets"])),
            "sicn_min": float(sicn.min()), "sicn_mean": float(sicn.mean()),
            "gamma_min": float(gamma.min()), "gamma_mean": float(gamma.mean()),
            "min_dihedral_deg": float(dihedral.min()),
            "poor_tets": int(np.sum(sicn < min_quality)), "min_quality": float(min_quality)}
