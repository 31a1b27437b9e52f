"""A scene's crossing: the cell's inputs read from its keys, checked, and the outputs of
`fruit skin` (crossing.npz, summary.json).

Units: mm, fF, counts. Inputs: the pitch ([grid].spacing_x_mm across the Tx yarns,
spacing_y_mm across the Rx yarns), the cover ([tracks].cover_mm: the depth where the
yarns cross), the yarn radius ([skin].yarn_radius_mm, default [tracks].track_radius_mm),
the insulation, permittivity and gap table ([skin]), gmsh's time limit
([mesh].time_limit_s).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import SceneError

if TYPE_CHECKING:
    from fruitcli.electrostatics.cell_geometry import CellSpec
    from fruitcli.electrostatics.crossing import CrossingTable
    from fruitcli.scene import Scene


TABLE_VERSION = 2
"""crossing.npz's format (`table_arrays`)."""


@dataclass(frozen=True)
class CrossingInputs:
    """Everything the crossing's table depends on (mm; permittivity relative)."""

    pitch_x_mm: float
    pitch_y_mm: float
    cover_mm: float
    yarn_radius_mm: float
    insulation_mm: float
    permittivity: float
    gaps_mm: tuple
    time_limit_s: float

    def to_dict(self) -> dict:
        d = asdict(self)
        d["gaps_mm"] = list(self.gaps_mm)
        return d


def crossing_inputs(scene: Scene) -> CrossingInputs:
    """The cell's inputs from a validated scene; SceneError naming the key when the
    yarns do not fit the design."""
    where = scene.path.name
    skin, tracks, grid = scene.skin, scene.tracks, scene.grid
    radius_key = "[skin].yarn_radius_mm"
    radius = skin.yarn_radius_mm
    if radius is None:
        radius_key, radius = "[tracks].track_radius_mm", tracks.track_radius_mm
    ins, cover = skin.insulation_mm, tracks.cover_mm
    pitch = min(grid.spacing_x_mm, grid.spacing_y_mm)
    if not radius > 0:
        raise SceneError(f"{where}: {radius_key}: expected > 0 (mm), got {radius:g}")
    if radius >= pitch / 2:
        raise SceneError(
            f"{where}: {radius_key}: expected less than half the pitch "
            f"({pitch / 2:g} mm, [grid].spacing_x_mm / spacing_y_mm), got "
            f"{radius:g}"
        )
    if radius >= cover:
        raise SceneError(
            f"{where}: {radius_key}: expected less than the cover "
            f"([tracks].cover_mm = {cover:g} mm), got {radius:g}"
        )
    if 2 * radius + ins / 2 >= cover:
        raise SceneError(
            f"{where}: {radius_key}: the upper yarn reaches the surface (two "
            f"radii plus half the insulation, {2 * radius + ins / 2:g} mm, "
            f"against [tracks].cover_mm = {cover:g} mm); expected a radius "
            f"below {(cover - ins / 2) / 2:g} mm"
        )
    _check_objects_fit(where, grid.spacing_x_mm, grid.spacing_y_mm)
    limit = scene.mesh.time_limit_s
    if not limit > 0:
        raise SceneError(f"{where}: [mesh].time_limit_s: expected > 0 (s), got {limit:g}")
    _check_cost(where, grid.spacing_x_mm, grid.spacing_y_mm, len(skin.gaps_mm))
    return CrossingInputs(
        float(grid.spacing_x_mm),
        float(grid.spacing_y_mm),
        float(cover),
        float(radius),
        float(ins),
        float(skin.permittivity),
        tuple(float(g) for g in skin.gaps_mm),
        float(limit),
    )


def _check_objects_fit(where: str, pitch_x_mm: float, pitch_y_mm: float) -> None:
    """SceneError naming the pitch's key when an object of the table is as wide as the
    crossing's cell or wider (the cell spans `crossing.REACH_PITCHES` pitches either
    side; its insulating side faces would mirror such an object into a ground plane)."""
    from fruitcli.electrostatics.crossing import REACH_PITCHES
    from fruitcli.electrostatics.touch_objects import OBJECTS

    key, pitch = min(
        (("[grid].spacing_x_mm", pitch_x_mm), ("[grid].spacing_y_mm", pitch_y_mm)),
        key=lambda kp: kp[1],
    )
    widest = max(OBJECTS.values(), key=lambda o: o.radius_mm)
    if widest.radius_mm >= REACH_PITCHES * pitch:
        raise SceneError(
            f"{where}: {key}: the {widest.name} ({2 * widest.radius_mm:g} mm wide) does not "
            f"fit in the crossing's cell ({REACH_PITCHES} pitches either side of the "
            f"crossing: {2 * REACH_PITCHES * pitch:g} mm); expected a pitch above "
            f"{widest.radius_mm / REACH_PITCHES:g} mm, got {pitch:g}"
        )


DEFAULT_SOLVE_S = 0.35
"""One position's solve on the default cell (s, 2 shared cores; bench_skin.py)."""

DEFAULT_FACTOR_MB = 270.0
"""Memory of the default cell's factorization and arrays (MB): the 150 MB of the
25,000-node cell it had, scaled as nodes^1.33 to its 39,000 nodes (`table_cost`)."""

MOST_TABLE_S = 1800.0
"""Longest estimated table `fruit skin` starts (s)."""

MOST_MEMORY_MB = 8000.0
"""Most estimated memory `fruit skin` starts with (MB)."""


def table_cost(pitch_x_mm: float, pitch_y_mm: float, gaps: int) -> tuple[float, float]:
    """(seconds, MB) a table is estimated to take: the cell's nodes grow with the pitch's
    area (the cell is 4 x 4 pitches), a solve as nodes^1.5 and the factor as
    nodes^1.33 (a 3D sparse Cholesky), one solve per object, gap and position."""
    from fruitcli.electrostatics.crossing import STEPS_PER_HALF_PITCH
    from fruitcli.electrostatics.touch_objects import OBJECTS

    ratio = max(pitch_x_mm * pitch_y_mm / (16.0 * 12.0), 0.05)
    solves = len(OBJECTS) * gaps * (STEPS_PER_HALF_PITCH + 1) ** 2
    seconds = solves * DEFAULT_SOLVE_S * ratio**1.5
    return seconds, DEFAULT_FACTOR_MB * ratio ** (4 / 3)


def _check_cost(where: str, pitch_x_mm: float, pitch_y_mm: float, gaps: int) -> None:
    """SceneError naming the key that makes the table too long or too large."""
    seconds, mb = table_cost(pitch_x_mm, pitch_y_mm, gaps)
    if mb > MOST_MEMORY_MB:
        raise SceneError(
            f"{where}: [grid].spacing_x_mm / spacing_y_mm: a crossing cell of "
            f"{pitch_x_mm:g} x {pitch_y_mm:g} mm is estimated at {mb / 1000:.1f} GB "
            f"(at most {MOST_MEMORY_MB / 1000:g} GB)"
        )
    if seconds > MOST_TABLE_S:
        key = "[skin].gaps_mm" if gaps > 10 else "[grid].spacing_x_mm / spacing_y_mm"
        raise SceneError(
            f"{where}: {key}: the crossing's table ({gaps} gaps, pitch {pitch_x_mm:g} x "
            f"{pitch_y_mm:g} mm) is estimated at {seconds / 60:.0f} min (at most "
            f"{MOST_TABLE_S / 60:g} min)"
        )


def cell_spec(inputs: CrossingInputs) -> CellSpec:
    """The crossing cell of a design (`crossing.cell_spec`)."""
    from fruitcli.electrostatics import crossing

    return crossing.cell_spec(
        inputs.pitch_x_mm,
        inputs.pitch_y_mm,
        inputs.cover_mm,
        inputs.yarn_radius_mm,
        inputs.insulation_mm,
        inputs.gaps_mm,
    )


def run_crossing(
    inputs: CrossingInputs, progress: Callable[[str], None] | None = None
) -> tuple[CrossingTable, dict]:
    """(CrossingTable, summary dict) of a design."""
    from fruitcli.electrostatics import crossing, equivalents

    spec = cell_spec(inputs)
    table = crossing.compute(
        spec,
        inputs.permittivity,
        inputs.gaps_mm,
        time_limit_s=inputs.time_limit_s,
        progress=progress,
    )
    summary = equivalents.summarize(table)
    summary["assumed"] = assumed_model()
    summary["inputs"] = inputs.to_dict()
    return table, _finite(summary)


def assumed_model() -> dict:
    """The phenomenological skin's defaults (`fruitcli.sensing.skin.forward`), for comparison."""
    from fruitcli.sensing.skin import forward

    return {
        "footprint_sigma_mm": forward.default_footprints_mm(),
        "gap_decay_mm": forward.GAP_DECAY_MM,
        "contact_counts": forward.CONTACT_COUNTS,
    }


def _finite(obj: object):
    """JSON-safe: non-finite floats become None."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    return obj


def table_arrays(table: CrossingTable) -> dict[str, np.ndarray]:
    """crossing.npz's arrays. Version 2: offsets out to `crossing.TABLE_PITCHES`
    pitches, solved on a cell of 3 x 3 crossings (version 1, without the key: half a
    pitch, one mirrored crossing); the arrays are the same."""
    return {
        "version": np.array(TABLE_VERSION),
        "c0_ff": np.array(table.c0_ff),
        "objects": np.array(table.objects),
        "gap_mm": table.gap_mm,
        "dx_mm": table.dx_mm,
        "dy_mm": table.dy_mm,
        "dc_ff": table.dc_ff,
        "deformations": np.array(table.deformations),
        "strain": table.strain,
        "curvature_per_mm": table.curvature_per_mm,
        "c_stretch_ff": table.c_stretch_ff,
        "c_bend_ff": table.c_bend_ff,
    }


def write_outputs(out_dir: Path, table: CrossingTable, summary: dict) -> None:
    """crossing.npz and summary.json into `out_dir`, together or not at all."""
    from fruitcli.fsutil import staged_dir, write_json

    with staged_dir(out_dir) as tmp:
        # numpy's stub: mypy matches **arrays against savez's allow_pickle (bool) too
        np.savez(tmp / "crossing.npz", **table_arrays(table))  # type: ignore[arg-type]
        write_json(tmp / "summary.json", summary)
