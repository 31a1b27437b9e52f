"""What the sensing stages read of the scene, as the typed inputs of the functions below
them: the gains detection divides by (`gain_inputs`), an electrostatic skin's crossing
table (`crossing_skin_inputs`), what calibrating the skin reads (`calibrate_inputs`) and
everything locating a recording reads (`locate_inputs` -> `LocateInputs`, with the files
of `LocateFiles`). Only these take the scene; `run_locate`, `locator_setup`,
`gain_division`, `skin.crossing_skin` and `skin.calibrate` take their records.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from fruitcli.scene import BoardSection, Scene, SkinSection, default_scene
from fruitcli.sensing.detection.gain_division import GainInputs
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.skin.calibrate import CalibrateInputs
from fruitcli.sensing.skin.crossing_skin import CrossingSkinInputs
from fruitcli.sensing.skin.models import SKIN_MODELS

if TYPE_CHECKING:
    from fruitcli.fem.reduced.model import ReducedModel


def or_defaults(scene: Scene | None) -> Scene:
    """The scene, or without one a scene at the schema's defaults."""
    return default_scene() if scene is None else scene


def gain_inputs(scene: Scene | None) -> GainInputs:
    """The scene's gain division (off without a scene); ``[skin].taxel_gain`` is read only
    when ``[detection].divide_by_gain`` is on."""
    if scene is None or not scene.detection.divide_by_gain:
        return GainInputs()
    return GainInputs(True, scene.skin.taxel_gain)


def crossing_skin_inputs(
    scene: Scene, crossing_dir: str | Path | None
) -> CrossingSkinInputs | None:
    """With ``[skin].model = "electrostatic"``: the crossing table's inputs, from
    `crossing_dir` (the skin stage's folder) or, without one, the cell's inputs read from
    the scene (`design.crossing_inputs`; SceneError naming the key when the yarns do not
    fit); None for a skin model without a crossing table."""
    if not SKIN_MODELS[scene.skin.model].computed:
        return None
    scale = scene.skin.counts_per_ff
    if crossing_dir is not None:
        return CrossingSkinInputs(scale, Path(crossing_dir))
    from fruitcli.electrostatics.design import crossing_inputs

    return CrossingSkinInputs(scale, crossing_inputs(scene))


def calibrate_inputs(scene: Scene) -> CalibrateInputs:
    """What `fruit calibrate` reads of the scene: its [board], ``[detection].
    baseline_frames`` and its [skin]."""
    return CalibrateInputs(scene.board, scene.detection.baseline_frames, scene.skin)


@dataclass(frozen=True)
class LocateInputs:
    """What locating a recording reads of the scene, the command's choices applied: the
    [board], the detection settings and ``[detection].project``, the [skin] table of the
    heights (None: the defaults), the gain division (`gains_csv`, the command's file,
    wins over the scene's), an electrostatic skin's crossing table (None: none) and the
    reduced model the taxels follow (None: the FEM states)."""

    board: BoardSection
    settings: Settings
    project: str = "none"
    skin: SkinSection | None = None
    gain: GainInputs = field(default_factory=GainInputs)
    gains_csv: str | Path | None = None
    crossing: CrossingSkinInputs | None = None
    reduced: ReducedModel | None = None


@dataclass(frozen=True)
class LocateFiles:
    """What `run_locate` reads and writes: the recording (`frames`), the taxel file, the
    FEM states (None: the taxels at rest), the output folder, and the body's closed
    surface at rest (None: not known) in `surface_unit`."""

    frames: str | Path
    taxels: str | Path
    states: str | Path | None
    out_dir: str | Path
    surface: str | Path | None = None
    surface_unit: str = "mm"


def locate_inputs(
    scene: Scene | None,
    *,
    baseline_frames: int | None = None,
    threshold_counts: float | None = None,
    method: str | None = None,
    hovers: bool | None = None,
    gains_csv: str | Path | None = None,
    skin_table: SkinSection | None = None,
    crossing_dir: str | Path | None = None,
    reduced: ReducedModel | None = None,
) -> LocateInputs:
    """`LocateInputs` of `scene` (None: the schema's defaults, no gain division, the
    default skin). The options that are not None win over the scene's [detection];
    `skin_table` (a [skin] table, e.g. `fruit calibrate`'s) over its [skin], and then no
    crossing table is used; `crossing_dir`: the skin stage's folder (an electrostatic
    skin's table is computed now without one)."""
    detection = or_defaults(scene).detection
    settings = Settings.from_scene(
        detection,
        baseline_frames=baseline_frames,
        threshold_counts=threshold_counts,
        method=method,
        hovers=hovers,
    )
    crossing = None
    if skin_table is None and scene is not None:
        skin_table = scene.skin
        crossing = crossing_skin_inputs(scene, crossing_dir)
    return LocateInputs(
        board=or_defaults(scene).board,
        settings=settings,
        project=detection.project,
        skin=skin_table,
        gain=gain_inputs(scene),
        gains_csv=gains_csv,
        crossing=crossing,
        reduced=reduced,
    )
