"""Reading and writing the mechanics' files: mesh.npz, states.npz, VTU for ParaView.

Arrays only (npz read with allow_pickle=False); lengths in mm.
"""

from __future__ import annotations

import base64
from pathlib import Path

import numpy as np

from fruitcli.errors import MeshError
from fruitcli.fsutil import atomic_path
from fruitcli.tables import read_npz_arrays

MESH_KEYS = ("nodes", "tets", "surface_tris", "chamber_names", "chamber_tris", "chamber_tri_owner")


def save_npz(path: Path, arrays: dict) -> None:
    """Write arrays to `path` atomically (uncompressed npz)."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **arrays)


def load_mesh(path: Path) -> dict:
    """mesh.npz as a dict of arrays; MeshError naming the file when keys are missing."""
    path = Path(path)
    mesh = read_npz_arrays(path, "npz mesh", MeshError, " (run `fruit tetra` first)")
    missing = [k for k in MESH_KEYS if k not in mesh]
    if missing:
        raise MeshError(f"{path}: missing array(s) {', '.join(missing)}")
    return mesh


def chamber_dict(mesh: dict) -> dict[str, np.ndarray]:
    """{name: (t, 3) triangles} from mesh.npz arrays."""
    return {
        str(name): mesh["chamber_tris"][mesh["chamber_tri_owner"] == k]
        for k, name in enumerate(mesh["chamber_names"])
    }


def _b64(array: np.ndarray) -> str:
    raw = np.ascontiguousarray(array).tobytes()
    return base64.b64encode(np.uint64(len(raw)).tobytes() + raw).decode("ascii")


def write_vtu(
    path: Path, nodes: np.ndarray, tets: np.ndarray, point_data: dict[str, np.ndarray] | None = None
) -> None:
    """Unstructured grid of linear (m, 4) or quadratic (m, 10, VTK's node order) tets
    (VTK XML, base64 binary), atomically."""
    n, (m, nen) = len(nodes), np.shape(tets)
    cell_type = 10 if nen == 4 else 24  # VTK_TETRA, VTK_QUADRATIC_TETRA

    def arr(name: str, a: np.ndarray, dtype: str, comps: int) -> str:
        return (
            f'<DataArray type="{dtype}" Name="{name}" NumberOfComponents="{comps}" '
            f'format="binary">{_b64(a)}</DataArray>'
        )

    pdata = "".join(
        arr(k, np.asarray(v, np.float64), "Float64", v.shape[1] if v.ndim > 1 else 1)
        for k, v in (point_data or {}).items()
    )
    text = (
        '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
        'byte_order="LittleEndian" header_type="UInt64">\n<UnstructuredGrid>\n'
        f'<Piece NumberOfPoints="{n}" NumberOfCells="{m}">\n'
        f"<PointData>{pdata}</PointData>\n"
        f"<Points>{arr('Points', np.asarray(nodes, np.float64), 'Float64', 3)}</Points>\n"
        "<Cells>"
        f"{arr('connectivity', np.asarray(tets, np.int64).ravel(), 'Int64', 1)}"
        f"{arr('offsets', nen * np.arange(1, m + 1, dtype=np.int64), 'Int64', 1)}"
        f"{arr('types', np.full(m, cell_type, np.uint8), 'UInt8', 1)}"
        "</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n"
    )
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text)
