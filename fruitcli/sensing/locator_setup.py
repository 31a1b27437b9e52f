"""What locating a recording is built from: the `Locator` of its taxels (at rest, at its
FEM state, along the states or from the reduced model), the projector onto the body's
surface, the skin's height model and an electrostatic skin's crossing table. Each takes
typed inputs (the scene's sections, `SurfaceInputs`, `CrossingSkinInputs`) that the
stages build (`inputs_stage`), never the scene. Units: mm, counts, kPa.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.geometry.body_surface import SurfaceProjector, body_surface
from fruitcli.scene import BoardSection, SkinSection
from fruitcli.sensing.detection.frames_to_touches import Locator
from fruitcli.sensing.detection.locate import States, match_chambers
from fruitcli.sensing.detection.methods import METHODS
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.frames.board import check_frame_shape
from fruitcli.sensing.frames.recording_chunks import ChunkedRecording
from fruitcli.tables import Taxels

if TYPE_CHECKING:
    from fruitcli.fem.reduced.model import ReducedModel
    from fruitcli.sensing.skin.crossing_heights import CrossingHeights
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin, CrossingSkinInputs
    from fruitcli.sensing.skin.heights import GapLaw, HeightModel


@dataclass(frozen=True)
class SurfaceInputs:
    """What projecting located points onto the body's surface reads: ``[detection].project``
    and the detection method (``[detection].method`` or the command's), and the body's
    closed surface at rest (`path`, None: not known) in `unit`."""

    project: str
    method: str
    path: str | Path | None = None
    unit: str = "mm"


def idle_settings(settings: Settings, meta: dict, n_frames: int, where: str) -> Settings:
    """`settings` with the baseline C0 taken over all the idle frames a recording says it
    begins with (its meta's ``baseline_frames``, which a bench writes) when they are more
    than ``[detection].baseline_frames``: C0's error is the noise over the square root
    of its frames, an offset on every touch of the recording that no mean of a touch's
    own frames removes. A meta count that is not an integer 1 .. N - 1: FrameError."""
    idle = meta.get("baseline_frames")
    if idle is None:
        return settings
    if isinstance(idle, bool) or not isinstance(idle, int) or not 1 <= idle < n_frames:
        raise FrameError(
            f"{where}: meta baseline_frames (the idle frames it begins with): expected an "
            f"integer 1 .. {n_frames - 1}, got {idle!r}"
        )
    return replace(settings, baseline_frames=idle) if idle > settings.baseline_frames else settings


def build_locator(
    board: BoardSection,
    taxels: Taxels,
    states: States | None,
    rec: ChunkedRecording,
    settings: Settings,
    where: str,
    reduced: ReducedModel | None = None,
    gain: np.ndarray | None = None,
    heights: HeightModel | None = None,
) -> tuple[Locator, np.ndarray | None]:
    """The Locator for a recording: rest positions, one state (meta "state", default 0)
    or the state path when the recording carries chamber pressures; with `reduced` (a
    ReducedModel of these taxels) and pressures in the recording, each frame's taxels
    from the reduced model at its pressures; `gain` (T,): the gains detection divides
    by (None: off); `heights`: the skin's height model (`Locator`); `board`: the scene's
    [board]. -> (locator, pressure)."""
    check_frame_shape(np.empty((0, *rec.frame_shape)), board, where)
    if reduced is not None and rec.pressure_kpa is not None:
        names = tuple(rec.chamber_names)
        missing = [c for c in reduced.chamber_names if c not in names]
        if missing:
            raise FrameError(
                f"{where}: no pressure for chamber {missing[0]!r} (recording has "
                f"{', '.join(names) or 'none'})"
            )
        cols = np.array([names.index(c) for c in reduced.chamber_names], np.int64)
        if reduced.coef_taxels.shape[1] != 3 * len(taxels):
            raise FrameError(
                f"{where}: {len(taxels)} taxels, but the reduced model follows "
                f"{reduced.coef_taxels.shape[1] // 3}"
            )
        rest = reduced.taxels(np.clip(np.zeros(len(cols)), reduced.lo, reduced.hi))
        return (
            Locator(
                taxels,
                board,
                rest,
                settings,
                where=where,
                reduced=reduced,
                gain=gain,
                heights=heights,
            ),
            rec.pressure_kpa[:, cols],
        )
    if states is None:
        return Locator(
            taxels, board, taxels.xyz_mm, settings, where=where, gain=gain, heights=heights
        ), None
    if rec.pressure_kpa is not None and states.n_states > 1:
        cols = match_chambers(rec.chamber_names, states, where)
        return (
            Locator(
                taxels,
                board,
                states.taxels_mm,
                settings,
                states.pressure_kpa,
                where,
                gain=gain,
                heights=heights,
            ),
            rec.pressure_kpa[:, cols],
        )
    state = int(rec.meta.get("state", 0))
    if not 0 <= state < states.n_states:
        raise FrameError(
            f"{where}: meta state {state} not in the states (0..{states.n_states - 1})"
        )
    return Locator(
        taxels, board, states.taxels_mm[state], settings, where=where, gain=gain, heights=heights
    ), None


def locator_taxels(states: States | None, state: int | None, taxels: Taxels) -> np.ndarray:
    """Taxel positions (T, 3) mm of the recording's state (rest without states)."""
    return taxels.xyz_mm if states is None else states.taxels_mm[state]


def surface_projector(
    surface: SurfaceInputs,
    rec: ChunkedRecording,
    states: States | None,
    pressure: np.ndarray | None,
    taxels: Taxels,
    where: str,
) -> SurfaceProjector | None:
    """The `SurfaceProjector` of ``[detection].project = "surface"``, or of the model
    method (its fitted points go onto the body's surface when the surface is known and
    the recording stays at one state); None otherwise."""
    surface_path = surface.path
    if surface.project != "surface":
        if not (model_on_surface(surface.method) and surface_path and pressure is None):
            return None
    if surface_path is None:
        raise FrameError(
            f"{where}: [detection].project = surface needs the body's surface "
            "(make-tracks' reduced.stl or [geometry].solid; `fruit locate "
            "--surface`)"
        )
    if pressure is not None:
        raise FrameError(
            f"{where}: [detection].project = surface works on a recording at "
            "one FEM state; this one follows the states by its pressures "
            "(not supported)"
        )
    state = None if states is None else int(rec.meta.get("state", 0))
    return SurfaceProjector(
        body_surface(surface_path, surface.unit),
        states,
        state,
        locator_taxels(states, state, taxels),
    )


def model_on_surface(method: str) -> bool:
    """Whether `method` places its touches on the body's surface when it is known."""
    return METHODS[method].refine == "model"


def skin_heights(
    skin: SkinSection | None,
    taxels: Taxels,
    settings: Settings,
    divided: bool,
    crossing: CrossingSkin | None = None,
) -> GapLaw | CrossingHeights:
    """The height model of a [skin] table (None: the defaults) for these taxels
    (`heights.gap_law`), or of the crossing's table `crossing` (a `CrossingSkin`) with
    the table's noise and gains (`crossing_heights`)."""
    from fruitcli.sensing.skin.forward import SkinParams
    from fruitcli.sensing.skin.heights import gap_law

    params = SkinParams.from_table(skin)
    if crossing is not None:
        from fruitcli.sensing.skin.crossing_heights import crossing_heights

        return crossing_heights(crossing, params, taxels.ids, settings.footprint, divided)
    return gap_law(params, taxels.ids, settings.footprint, divided)


def electrostatic_skin(
    crossing: CrossingSkinInputs | None, progress: Callable[[str], None] | None = None
) -> CrossingSkin | None:
    """The crossing's table in counts (`crossing_skin.crossing_skin`: from the skin
    stage's folder, or computed now without one) for an electrostatic skin; None (a skin
    without a crossing table) for another [skin].model."""
    if crossing is None:
        return None
    from fruitcli.sensing.skin.crossing_skin import crossing_skin

    return crossing_skin(crossing, progress)
