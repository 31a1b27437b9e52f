"""The FEM behind `fruit live --online`: the scene's mesh or reduced model, built through
the planner into ``out/<scene name>`` when needed, and the solver that follows the measured
chamber pressures (mm, kPa).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.workflow import planner
from fruitcli.workflow.scene_outputs import shared_outputs
from fruitcli.workflow.stage_paths import taxels_path

if TYPE_CHECKING:
    from click._termui_impl import ProgressBar

    from fruitcli.fem.online import OnlineSolver, ReducedOnline
    from fruitcli.fem.reduced.model import ReducedModel
    from fruitcli.scene import Scene
    from fruitcli.tables import Taxels


def online_products(
    scene: Scene,
    scene_path: str | Path,
    taxels_csv: str | Path | None,
    pressure_port: str | None,
    progress: Callable[[str], None] | None,
) -> tuple[str | Path | None, Path]:
    """(taxels CSV, mesh.npz) for `fruit live --online`: the scene's stages up to tetra,
    run into out/<scene name> when needed (one planner run); given taxels are kept."""

    if not pressure_port:
        raise FrameError("--online: needs --pressure-port, the source of the pressures")
    if not scene.chambers:
        raise FrameError(f"{scene_path}: --online: the scene has no [[geometry.chamber]]")
    out = Path("out") / scene.name
    steps = planner.run(scene, out, until="tetra", progress=progress, shared=shared_outputs(out))
    skipped = [st for st in steps if st.stage == "tetra" and st.action == "not needed"]
    if skipped:
        raise FrameError(
            f"{scene_path}: --online: the scene is not meshed ({skipped[0].reason}); "
            "give [actuation] pressures for its chambers"
        )
    ctx = planner.Context(out)
    return taxels_csv or taxels_path(scene, ctx), ctx.dir("tetra") / "mesh.npz"


def online_reduced(
    scene: Scene,
    scene_path: str | Path,
    taxels_csv: str | Path | None,
    pressure_port: str | None,
    progress: Callable[[str], None],
    bar: Callable[[int], ProgressBar[Any]] | None = None,
) -> tuple[str | Path | None, ReducedModel]:
    """(taxels CSV, ReducedModel) for `fruit live --online --model reduced`: the scene's
    reduced model, built into out/<scene name>/reduce when missing or stale."""
    from fruitcli.workflow.reduced_model import ensure_reduced

    if not pressure_port:
        raise FrameError("--online: needs --pressure-port, the source of the pressures")
    if not scene.chambers:
        raise FrameError(f"{scene_path}: --online: the scene has no [[geometry.chamber]]")
    out = Path("out") / scene.name
    reduced = ensure_reduced(
        scene, out, taxels_csv, progress, label=f"{scene_path}: --online", bar=bar
    )
    progress(reduced.describe())
    return taxels_csv or taxels_path(scene, planner.Context(out)), reduced


def reduced_source(
    reduced: ReducedModel, taxels: Taxels, taxels_csv: str | Path | None
) -> ReducedOnline:
    """The live loop's ReducedOnline; FrameError when the model follows other taxels."""
    from fruitcli.fem.online import ReducedOnline

    n = reduced.coef_taxels.shape[1] // 3
    if n != len(taxels):
        raise FrameError(
            f"{taxels_csv}: {len(taxels)} taxels, but the reduced model follows "
            f"{n}: rebuild it (fruit run SCENE --until reduce)"
        )
    return ReducedOnline(reduced)


def online_solver(
    scene: Scene, mesh_npz: Path, taxels_xyz: np.ndarray, progress: Callable[[str], None]
) -> OnlineSolver:
    """The OnlineSolver of `fruit live --online` on the scene's mesh, with the taxels
    mapped into it."""
    from fruitcli.fem import io
    from fruitcli.fem.elements import barycentric
    from fruitcli.fem.online import OnlineSolver
    from fruitcli.fem.stage import build_model, solver_options

    model = build_model(scene, io.load_mesh(mesh_npz))
    tet, w, _ = barycentric.locate(model.rest, model.tets, taxels_xyz)
    progress(f"online FEM: {len(model.tets)} tets, chambers {', '.join(model.chamber_names)}")
    return OnlineSolver(
        model,
        tet,
        w,
        solver_options(scene),
        solver_options(scene, first_state=True, jig=bool(model.jigs)),
    )
