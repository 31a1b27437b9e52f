"""The closed surfaces that bound the FEM body: the outer solid and the chambers.

A shell is a dict: ``{"name", "kind": "surface" | "box" | "ellipsoid", "vertices",
"faces"}`` (mm) with ``"params"`` for the analytic kinds (meshed by gmsh/OCC). Every
shell also carries a triangle surface (analytic ones a fine polyhedral stand-in) for
the checks: closed, positive volume, chambers inside the solid and apart.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import GeometryError, MeshError, SceneError
from fruitcli.fem.tolerances import INSIDE_VOLUME_MM3

if TYPE_CHECKING:
    from manifold3d import Manifold
    from numpy.typing import ArrayLike


def load_surface(
    path: str | Path, what: str, error: type[Exception] = SceneError, scale: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (v, 3) mm and faces (f, 3) of a closed, consistently wound surface file
    (its coordinates times `scale`: 1000 for a file in metres)."""
    import trimesh

    path = Path(path)
    if not path.exists():
        raise error(f"{what}: file not found: {path}")
    if path.suffix.lower() == ".stl":
        from fruitcli.geometry.mesh.load import check_binary_stl

        try:
            check_binary_stl(path)
        except GeometryError as exc:
            raise error(f"{what}: {exc}") from None
    try:
        mesh = trimesh.load_mesh(path, process=True, force="mesh")
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise error(f"{what}: cannot read {path}: {exc}") from None
    if len(mesh.faces) < 4 or not mesh.is_watertight:
        raise error(f"{what}: {path} is not a closed surface (watertight mesh expected)")
    if not mesh.is_winding_consistent:
        raise error(f"{what}: {path} has inconsistent triangle winding")
    if mesh.volume < 0:
        mesh.invert()
    return np.asarray(mesh.vertices, float) * scale, np.asarray(mesh.faces, np.int64)


def surface_shell(name: str, vertices: ArrayLike, faces: ArrayLike) -> dict:
    return {
        "name": name,
        "kind": "surface",
        "vertices": np.asarray(vertices, float),
        "faces": np.asarray(faces, np.int64),
    }


def box_shell(name: str, lo: ArrayLike, hi: ArrayLike) -> dict:
    import trimesh

    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = trimesh.creation.box(bounds=[lo, hi])
    return {
        "name": name,
        "kind": "box",
        "params": np.concatenate([lo, hi - lo]),
        "vertices": np.asarray(m.vertices),
        "faces": np.asarray(m.faces),
    }


def ellipsoid_shell(name: str, center_mm: ArrayLike, radii_mm: ArrayLike) -> dict:
    import trimesh

    c, r = np.asarray(center_mm, float), np.asarray(radii_mm, float)
    m = trimesh.creation.icosphere(subdivisions=4)
    # circumscribed stand-in (a little larger than the true ellipsoid) for the checks
    v = np.asarray(m.vertices) * r * 1.01 + c
    return {
        "name": name,
        "kind": "ellipsoid",
        "params": np.concatenate([c, r]),
        "vertices": v,
        "faces": np.asarray(m.faces),
    }


def _manifold(shell: dict) -> Manifold:
    import manifold3d

    mesh = manifold3d.Mesh(
        vert_properties=np.asarray(shell["vertices"], np.float32),
        tri_verts=np.asarray(shell["faces"], np.uint32),
    )
    man = manifold3d.Manifold(mesh)
    if man.status() != manifold3d.Error.NoError:
        raise MeshError(
            f"{shell['name']}: surface is not a valid closed manifold ({man.status().name})"
        )
    return man


def check_layout(outer: dict, chambers: list[dict], where: str = "scene") -> None:
    """Refuse chambers that poke out of the solid or overlap each other (MeshError
    naming the scene file `where` and the chamber). Ctrl-C waits for manifold3d's calls."""
    from fruitcli.interrupts import deferred_sigint

    with deferred_sigint():
        _check_layout(outer, chambers, where)


def _check_layout(outer: dict, chambers: list[dict], where: str) -> None:
    body = _manifold(outer)
    mans: list[Manifold] = []
    for ch in chambers:
        man = _manifold(ch)
        vol = man.volume()
        outside = (man - body).volume()
        if outside > INSIDE_VOLUME_MM3 * max(vol, 1.0) + 1e-9:
            raise MeshError(
                f"{where}: [[geometry.chamber]] '{ch['name']}': {outside:.3g} mm^3 "
                f"of it lies outside the solid {outer['name']} (chambers must be "
                "inside the body)"
            )
        for other, oman in zip(chambers, mans, strict=False):
            if (man ^ oman).volume() > INSIDE_VOLUME_MM3 * max(vol, 1.0) + 1e-9:
                raise MeshError(
                    f"{where}: [[geometry.chamber]] '{ch['name']}' intersects "
                    f"[[geometry.chamber]] '{other['name']}'"
                )
        mans.append(man)
