"""Mesh the crossing cell in a child process that is killed after a time limit.

``python -m fruitcli.electrostatics.cell_mesh SPEC.json OUT.npz ORDER`` meshes
`cell_geometry.build` and writes the `occ_mesh.TetMesh` arrays; the parent
(`mesh_cell`) runs it in its own process group, as `fruitcli.fem.meshing.tetra` does,
because gmsh can ignore polite signals for a long time.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from fruitcli.electrostatics.cell_geometry import CellSpec, build
from fruitcli.electrostatics.occ_mesh import TetMesh, mesh_model, start
from fruitcli.errors import MeshError


def mesh_cell(
    spec: CellSpec, order: int, time_limit_s: float, time_limit_key: str = "[mesh].time_limit_s"
) -> TetMesh:
    """The cell's tet mesh; MeshError naming `time_limit_key` when gmsh takes longer."""
    with tempfile.TemporaryDirectory(prefix="fruit-cell-") as tmp:
        tmp = Path(tmp)
        (tmp / "spec.json").write_text(json.dumps(spec.to_dict()))
        cmd = [
            sys.executable,
            "-m",
            "fruitcli.electrostatics.cell_mesh",
            str(tmp / "spec.json"),
            str(tmp / "mesh.npz"),
            str(order),
        ]
        env = dict(
            os.environ,
            PYTHONPATH=os.pathsep.join(
                [str(Path(__file__).resolve().parents[2]), os.environ.get("PYTHONPATH", "")]
            ),
        )
        proc = subprocess.Popen(
            cmd,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            start_new_session=True,
            env=env,
            text=True,
        )
        try:
            _, err = proc.communicate(timeout=time_limit_s)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            raise MeshError(
                f"crossing cell: gmsh did not finish within {time_limit_key} = "
                f"{time_limit_s:g} s (killed)"
            ) from None
        except BaseException:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            raise
        if proc.returncode != 0 or not (tmp / "mesh.npz").exists():
            lines = [ln for ln in err.strip().splitlines() if ln.strip()]
            msg = lines[-1] if lines else f"exit code {proc.returncode}"
            raise MeshError(f"crossing cell: meshing failed: {msg}")
        with np.load(tmp / "mesh.npz", allow_pickle=False) as data:
            return TetMesh.from_arrays({k: data[k] for k in data.files})


def main(argv: list[str]) -> int:
    raw = json.loads(Path(argv[0]).read_text())
    spec = CellSpec(
        **{
            **raw,
            "levels_mm": tuple(raw["levels_mm"]),
            "points_mm": tuple(map(tuple, raw["points_mm"])),
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
    np.savez(argv[1], **mesh.to_arrays())
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
