"""A scene's output folder as the commands use it: the sibling scenes' folders that may
lend a stage's outputs, and the taxels and states a command needs, made on demand.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from fruitcli.workflow import planner
from fruitcli.workflow.stage_paths import states_path, taxels_path

if TYPE_CHECKING:
    from fruitcli.scene import Scene
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin


def shared_outputs(out_dir: Path) -> Path | None:
    """The folder holding the scene output folder `out_dir` and its siblings (out/ for
    out/<scene>), when it exists: a stage whose inputs equal a sibling's is copied from
    there instead of run again (`planner.run(shared=...)`)."""
    parent = Path(out_dir).resolve().parent
    return parent if parent.is_dir() else None


def scene_products(
    scene: Scene, out_root: Path | None = None, progress: Callable[[str], None] | None = None
) -> tuple[Path | None, Path | None]:
    """Taxels CSV and states.npz (or None) of a scene, running the stages that make them
    (into `out_root`, default out/<scene name>) and reusing what is already there."""
    out = Path(out_root) if out_root else Path("out") / scene.name
    # simulate's upstream makes the taxels; stages the scene does not need are skipped
    planner.run(scene, out, until="simulate", progress=progress, shared=shared_outputs(out))
    ctx = planner.Context(out)
    return taxels_path(scene, ctx), states_path(scene, ctx)


def crossing_response(
    scene: Scene, out_root: Path | None = None, progress: Callable[[str], None] | None = None
) -> CrossingSkin | None:
    """The scene's electrostatic skin (`crossing_skin.CrossingSkin`) with ``[skin].model =
    "electrostatic"``, else None: the skin stage's table (run into `out_root`, default
    out/<scene name>, reused while the cell's inputs are unchanged) or, when nothing in
    the scene needs that stage, computed now."""
    from fruitcli.sensing.inputs_stage import crossing_skin_inputs
    from fruitcli.sensing.locator_setup import electrostatic_skin
    from fruitcli.workflow.stage_paths import electrostatic

    if not electrostatic(scene):
        return None
    out = Path(out_root) if out_root else Path("out") / scene.name
    steps = planner.run(scene, out, until="skin", progress=progress, shared=shared_outputs(out))
    made = any(s.stage == "skin" and s.action != "not needed" for s in steps)
    folder = planner.Context(out).dir("skin") if made else None
    return electrostatic_skin(crossing_skin_inputs(scene, folder), progress)
