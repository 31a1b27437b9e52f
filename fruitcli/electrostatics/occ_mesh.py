"""Tetrahedral meshes of OpenCASCADE models for the field solver, from gmsh.

Units: mm. A caller builds its geometry in the current gmsh model (OCC kernel), names
physical volumes (dielectrics) and physical surfaces (conductors), sets its sizes and
calls `mesh_model`. Order 2 asks gmsh for 10-node tets whose edge nodes lie on the CAD
surfaces (curved conductors), reordered to VTK's node order (`fruitcli.fem.elements`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.interrupts import ignore_sigpipe

if TYPE_CHECKING:
    from types import ModuleType

GMSH_TET = {1: 4, 2: 11}  # gmsh element type of 4- and 10-node tets
GMSH_TO_VTK_TET10 = np.array([0, 1, 2, 3, 4, 5, 6, 7, 9, 8])
"""gmsh's edge nodes (0,1), (1,2), (2,0), (3,0), (3,2), (3,1) to VTK's (0,1), (1,2), (0,2),
(0,3), (1,3), (2,3)."""

HIGH_ORDER_OPTIMIZE = 2
"""gmsh's Mesh.HighOrderOptimize (2: elastic and optimization): edge nodes moved onto a
coarsely meshed curved surface can fold an element; this unfolds it."""


@dataclass
class TetMesh:
    """nodes (N, 3) mm, tets (m, 4) or (m, 10), `region` (m,) index into `regions`
    (physical volume names), `surfaces` name -> node indices (physical surfaces)."""

    nodes: np.ndarray
    tets: np.ndarray
    region: np.ndarray
    regions: tuple[str, ...]
    surfaces: dict[str, np.ndarray]
    order: int

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {
            "nodes": self.nodes,
            "tets": self.tets,
            "region": self.region,
            "regions": np.array(self.regions),
            "order": np.array(self.order),
        }
        for name, idx in self.surfaces.items():
            out[f"surface_{name}"] = idx
        return out

    @classmethod
    def from_arrays(cls, data: Mapping[str, np.ndarray]) -> TetMesh:
        surfaces = {
            k.removeprefix("surface_"): np.asarray(data[k])
            for k in data
            if k.startswith("surface_")
        }
        return cls(
            np.asarray(data["nodes"]),
            np.asarray(data["tets"]),
            np.asarray(data["region"]),
            tuple(str(s) for s in data["regions"]),
            surfaces,
            int(data["order"]),
        )


def mesh_model(gmsh: ModuleType, order: int = 1) -> TetMesh:
    """Mesh the current gmsh model in 3D at `order` and collect its physical groups."""
    gmsh.model.mesh.generate(3)
    if order == 2:
        gmsh.option.setNumber("Mesh.HighOrderOptimize", HIGH_ORDER_OPTIMIZE)
        gmsh.model.mesh.setOrder(2)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    nodes = coords.reshape(-1, 3)
    per_tet = 4 if order == 1 else 10
    blocks: list[np.ndarray] = []  # each region's tets
    region: list[np.ndarray] = []
    regions: list[str] = []
    for dim, ptag in gmsh.model.getPhysicalGroups(3):
        regions.append(gmsh.model.getPhysicalName(dim, ptag))
        for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, ptag):
            _, enodes = gmsh.model.mesh.getElementsByType(GMSH_TET[order], ent)
            t = index[enodes.astype(np.int64)].reshape(-1, per_tet)
            blocks.append(t if order == 1 else t[:, GMSH_TO_VTK_TET10])
            region.append(np.full(len(t), len(regions) - 1))
    surfaces = {}
    for dim, ptag in gmsh.model.getPhysicalGroups(2):
        ntags, _ = gmsh.model.mesh.getNodesForPhysicalGroup(dim, ptag)
        surfaces[gmsh.model.getPhysicalName(dim, ptag)] = np.unique(index[ntags.astype(np.int64)])
    tets = np.concatenate(blocks)
    used = np.unique(tets)
    renumber = np.full(len(nodes), -1)
    renumber[used] = np.arange(len(used))
    surfaces = {k: renumber[v][renumber[v] >= 0] for k, v in surfaces.items()}
    nodes, tets = nodes[used].copy(), renumber[tets]
    if order == 2:
        straighten_folded(nodes, tets)
    return TetMesh(nodes, tets, np.concatenate(region), tuple(regions), surfaces, order)


def straighten_folded(nodes: np.ndarray, tets10: np.ndarray, rounds: int = 5) -> int:
    """Put the edge nodes of every 10-node tet whose Jacobian is not positive at a corner
    or quadrature point back at its edge midpoints (in place; e.g. a flat tet with all
    corners on a coarsely meshed sphere); returns how many elements were straightened."""
    from fruitcli.fem.elements.lagrange import TET10_EDGES, tet_rule, tet_shape_gradients

    dref = tet_shape_gradients(np.vstack([np.eye(4), tet_rule(2)[0]]), 2)
    done = 0
    for _ in range(rounds):
        x = nodes[tets10]
        bad = np.linalg.det(np.einsum("mai,qaj->mqij", x, dref)).min(axis=1) <= 0
        if not bad.any():
            break
        t = tets10[bad]
        nodes[t[:, 4:]] = 0.5 * (nodes[t[:, TET10_EDGES[:, 0]]] + nodes[t[:, TET10_EDGES[:, 1]]])
        done += int(bad.sum())
    return done


def start(name: str = "fruit-electrostatics") -> ModuleType:
    """Initialize gmsh quietly on one thread; returns the module."""
    import gmsh

    gmsh.initialize([name], readConfigFiles=False)
    ignore_sigpipe()  # gmsh leaves SIGPIPE at its default
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.add(name)
    return gmsh
