"""Mesh the crossing cell in a child process that is killed after a time limit.

``python -m fruitcli.electrostatics.cell_mesh SPEC.json OUT.npz ORDER`` meshes
`cell_geometry.build` and writes the `occ_mesh.TetMesh` arrays; the parent
(`mesh_cell`) runs it through `fruitcli.fem.meshing.child_process`, killed at the time
limit and ended with its parent.
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from fruitcli.electrostatics.cell_geometry import CellSpec, build
from fruitcli.electrostatics.occ_mesh import TetMesh, mesh_model, start
from fruitcli.errors import MeshError
from fruitcli.fem.meshing.child_process import follow_parent, last_error_line, run_module


def mesh_cell(
    spec: CellSpec, order: int, time_limit_s: float, time_limit_key: str = "[mesh].time_limit_s"
) -> TetMesh:
    """The cell's tet mesh; MeshError naming `time_limit_key` when gmsh takes longer."""
    with tempfile.TemporaryDirectory(prefix="fruit-cell-") as tmp_name:
        tmp = Path(tmp_name)
        (tmp / "spec.json").write_text(json.dumps(spec.to_dict()))
        args = [str(tmp / "spec.json"), str(tmp / "mesh.npz"), str(order)]
        try:
            code, err = run_module("fruitcli.electrostatics.cell_mesh", args, time_limit_s)
        except TimeoutError:
            raise MeshError(
                f"crossing cell: gmsh did not finish within {time_limit_key} = "
                f"{time_limit_s:g} s (killed)"
            ) from None
        if code != 0 or not (tmp / "mesh.npz").exists():
            raise MeshError(f"crossing cell: meshing failed: {last_error_line(err, code)}")
        with np.load(tmp / "mesh.npz", allow_pickle=False) as data:
            return TetMesh.from_arrays({k: data[k] for k in data.files})


def main(argv: list[str]) -> int:
    follow_parent()
    raw = json.loads(Path(argv[0]).read_text())
    spec = CellSpec(
        **{
            **raw,
            "levels_mm": tuple(raw["levels_mm"]),
            "points_mm": tuple(map(tuple, raw["points_mm"])),
            "touch_box_mm": tuple(raw["touch_box_mm"]),
        }
    )
    gmsh = start("fruit-cell")
    try:
        build(gmsh, spec)
        mesh = mesh_model(gmsh, int(argv[2]))
    except Exception as exc:  # one line for the parent
        print(
            f"gmsh: {str(exc).strip().splitlines()[-1] if str(exc).strip() else exc!r}",
            file=sys.stderr,
        )
        return 3
    finally:
        gmsh.finalize()
    # numpy's stub: mypy matches **arrays against savez's allow_pickle (bool) too
    np.savez(argv[1], **mesh.to_arrays())  # type: ignore[arg-type]
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
