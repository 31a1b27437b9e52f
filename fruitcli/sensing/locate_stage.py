"""The locate stage: every frame of a recording detected and located, chunk by chunk
(touches.csv; measured.csv for a bench's frames). Units: mm, counts, kPa, s.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Required, TypedDict

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.fsutil import write_csv
from fruitcli.geometry.body_surface import SurfaceProjector
from fruitcli.sensing.bench_stage import POINT_HEADER
from fruitcli.sensing.detection.frames_to_touches import CHUNK_FRAMES
from fruitcli.sensing.detection.locate import load_states
from fruitcli.sensing.detection.model_fit import FIT_MODEL
from fruitcli.sensing.detection.touch_table import TOUCH, TouchTable
from fruitcli.sensing.frames.recording_chunks import open_recording
from fruitcli.sensing.inputs_stage import LocateFiles, LocateInputs
from fruitcli.sensing.locator_setup import (
    SurfaceInputs,
    build_locator,
    electrostatic_skin,
    idle_settings,
    skin_heights,
    surface_projector,
)
from fruitcli.sensing.outputs.touch_csv import touch_bytes, touch_csv
from fruitcli.tables import read_taxels
from fruitcli.time_left import time_left

if TYPE_CHECKING:
    from fruitcli.sensing.detection.frames_to_touches import Locator
    from fruitcli.sensing.frames.recording_chunks import ChunkedRecording


class LocateSummary(TypedDict, total=False):
    """What `run_locate` did: frames, touches written, lines skipped, time (s) and
    frames per second, the touches CSV; the projection onto the surface (touches moved,
    mean and max distance, mm); how a recording with pressures was followed ("reduced"
    or "full", with the frames outside the reduced model's range or the distances to the
    state path); a bench's measured.csv with its samples and the samples missed."""

    frames: Required[int]
    touches: Required[int]
    skipped_lines: Required[int]
    seconds: Required[float]
    frames_per_s: Required[float]
    touches_csv: Required[str]
    projected_to_surface: dict[str, float]
    model: str
    frames_outside_reduced_range: int
    pressure_path: dict
    measured_csv: str
    samples: int
    samples_missed: int


def run_locate(
    inputs: LocateInputs,
    files: LocateFiles,
    progress: Callable[[str], None] | None = None,
    chunk_frames: int = CHUNK_FRAMES,
    workers: int | None = None,
) -> LocateSummary:
    """Detect and locate every frame of a recording; write touches.csv (+ measured.csv).
    `inputs`: what it reads of the scene (`inputs_stage.locate_inputs`); `files`: the
    recording, taxels, states, output folder and body surface. The recording is read,
    detected and written `chunk_frames` frames at a time, on `workers` threads
    (default: the CPUs this process may use, at most 4). With ``[detection].project =
    "surface"`` the located points are moved to the nearest point of the body's surface
    (`files.surface`, at rest, in `files.surface_unit`; carried by the recording's FEM
    state). With `inputs.reduced` (a ReducedModel), a recording with chamber pressures
    takes each frame's taxels from it (`build_locator`). Activations are divided by the
    taxels' gains with `inputs.gains_csv` or the scene's ``[detection].divide_by_gain``
    (`gain_division`). Heights, strengths and sizes come from `inputs.skin` (a [skin]
    table: the scene's or e.g. `fruit calibrate`'s; `fruitcli.sensing.skin.heights.
    gap_law`) or, for an electrostatic skin, the crossing's table (`crossing_heights`);
    hovers are written with kind hover and are never bench samples."""
    from fruitcli.sensing.detection.gain_division import detection_gain

    say = progress or (lambda msg: None)
    frames_path, out_dir = files.frames, Path(files.out_dir)
    taxels = read_taxels(files.taxels, FrameError)
    board, settings = inputs.board, inputs.settings
    states = None if files.states is None else load_states(files.states, len(taxels))
    if settings.threshold_counts <= 0:
        raise FrameError(f"threshold: expected > 0 counts, got {settings.threshold_counts}")
    where = str(frames_path)
    gain = detection_gain(inputs.gain, taxels, inputs.gains_csv)
    crossing = electrostatic_skin(inputs.crossing, say)
    heights = skin_heights(inputs.skin, taxels, settings, gain is not None, crossing)
    if workers is None:
        workers = min(4, _usable_cpus())
    surface = SurfaceInputs(inputs.project, settings.method, files.surface, files.surface_unit)
    with open_recording(frames_path, board.rows, board.cols, board.format, "read") as rec:
        settings = idle_settings(settings, rec.meta, len(rec), where)
        locator, pressure = build_locator(
            board, taxels, states, rec, settings, where, inputs.reduced, gain, heights
        )
        projector = surface_projector(surface, rec, states, pressure, taxels, where)
        if projector is not None:
            locator.use_surface(projector.normal, projector.distance)
        only_fitted = settings.method == "model" and inputs.project != "surface"
        say(
            f"{len(rec)} frames, {len(taxels)} taxels, {rec.skipped_lines} lines skipped"
            + (
                ""
                if gain is None
                else f"; activations divided by the taxel gains ({gain.min():.3f}-{gain.max():.3f})"
            )
        )
        t0 = time.perf_counter()
        baseline = locator.baseline(rec.read(0, settings.baseline_frames), where, len(rec))
        header = _touches_header(frames_path, locator.model is not None)
        run = _Written(out_dir / "touches.csv", header, projector, only_fitted, t0)
        _write_touches(locator, rec, baseline, pressure, run, chunk_frames, workers, say)
        dt = time.perf_counter() - t0
    result: LocateSummary = {
        "frames": len(rec),
        "touches": run.rows,
        "skipped_lines": rec.skipped_lines,
        "seconds": dt,
        "frames_per_s": len(rec) / max(dt, 1e-9),
        "touches_csv": str(out_dir / "touches.csv"),
    }
    if projector is not None:
        result["projected_to_surface"] = _projected(run.moved, say)
    if pressure is not None:
        _followed(result, locator, rec, pressure, out_dir, say)
    _measured(result, rec, run.sampled, out_dir, say)
    say(f"{run.rows} touches, {result['frames_per_s']:.0f} frames/s")
    return result


@dataclass
class _Written:
    """What `_write_touches` is given: the CSV and its comment lines, the projector onto
    the body's surface (or None), whether it moves only the model's fitted points, and
    when the run started (perf_counter s); and what it gathers: the rows written, the
    bench samples' touches and [touches projected, sum and max of the distances moved
    (mm)]."""

    csv: Path
    header: list[str]
    projector: SurfaceProjector | None
    only_fitted: bool
    started: float
    rows: int = 0
    sampled: list = field(default_factory=list)
    moved: list = field(default_factory=lambda: [0, 0.0, 0.0])


def _write_touches(
    locator: Locator,
    rec: ChunkedRecording,
    baseline: np.ndarray,
    pressure: np.ndarray | None,
    run: _Written,
    chunk_frames: int,
    workers: int,
    say: Callable[[str], None],
):
    """Detect the recording `chunk_frames` frames at a time on `workers` threads and
    write the touches CSV; progress every 2 s; the frames' CRC-32 checked before the
    file appears. Fills `run` (a `_Written`)."""
    model = locator.model is not None
    projector = run.projector

    def rows(table: TouchTable):  # in the worker thread
        dist = None
        if projector is not None:
            picked: slice | np.ndarray = slice(None)
            if run.only_fitted:  # the model's points; the N9 points it kept stay as they are
                picked = np.flatnonzero(table.fit == FIT_MODEL)
            table.xyz_mm[picked], dist = projector.project(table.xyz_mm[picked])
        keep = None if rec.sample is None else _sample_touches(table, rec.sample)
        return touch_bytes(table, rec.t_s, model), len(table), keep, dist

    done, shown, first = 0, run.started, None
    with touch_csv(run.csv, run.header, model) as out:
        for data, count, keep, dist in locator.chunks(
            rec.read, len(rec), baseline, pressure, chunk_frames, rows, workers
        ):
            out.write(data, count)
            if keep is not None:
                run.sampled.append(keep)
            if dist is not None and len(dist):
                run.moved = [
                    run.moved[0] + len(dist),
                    run.moved[1] + float(dist.sum()),
                    max(run.moved[2], float(dist.max())),
                ]
            done = min(done + chunk_frames, len(rec))
            if first is None:  # the rate is taken after the first chunk (compiles)
                first = (time.perf_counter(), done)
            if time.perf_counter() - shown > 2.0:
                shown = time.perf_counter()
                say(
                    f"{done} of {len(rec)} frames, {out.rows} touches"
                    + time_left(first, done, len(rec))
                )
        rec.verify()  # the frames' CRC-32, before touches.csv appears
    run.rows = out.rows


def _touches_header(frames_path: str | os.PathLike, model: bool) -> list[str]:
    """The comment lines at the top of touches.csv (units of every column)."""
    return [
        f"touches of {Path(frames_path).name}: frame index from 0 "
        "(baseline frames included), t_s in s, i, j fractional grid "
        "coordinates, x_mm, y_mm, z_mm in mm, peak in counts, height_mm "
        "above the surface and height_err_mm its uncertainty in mm, strength "
        "(1: contact), size_mm footprint sigma in mm, kind touch or hover"
        + (
            "; pos_err_mm the model fit's 1-sigma radius in mm, residual its RMS "
            "weighted residual (1: at the noise), fit model or n9 (fit failed, N9 "
            "point kept)"
            if model
            else ""
        )
    ]


def _projected(moved: list, say: Callable[[str], None]) -> dict[str, float]:
    """The summary of the touches moved onto the body's surface."""
    projected = {"touches": moved[0], "mean_mm": moved[1] / max(moved[0], 1), "max_mm": moved[2]}
    say(
        f"projected {moved[0]} touches onto the surface: moved "
        f"{projected['mean_mm']:.2f} mm on average, {projected['max_mm']:.2f} mm at most"
    )
    return projected


def _followed(
    result: LocateSummary,
    locator: Locator,
    rec: ChunkedRecording,
    pressure: np.ndarray,
    out_dir: Path,
    say: Callable[[str], None],
) -> None:
    """Into `result`: how a recording with chamber pressures was followed: by the
    reduced model (frames outside its range counted) or along the FEM states (frames far
    from the simulated path counted, not hidden)."""
    if locator.reduced is not None:
        outside = int(locator.reduced.outside(pressure).sum())
        say(
            f"taxels from the reduced model at each frame's pressures "
            f"({locator.reduced.describe()}); {outside} of {len(rec)} frames outside its "
            "range (clamped to it)"
        )
        result["model"] = "reduced"
        result["frames_outside_reduced_range"] = outside
        return
    from fruitcli.sensing.detection.pressure_path import report_off_path

    state_pressure = locator.state_pressure_kpa
    assert state_pressure is not None  # a recording with pressures follows the states' path
    off_path = report_off_path(rec, pressure, state_pressure, out_dir, say)
    result["model"] = "full"
    result["pressure_path"] = off_path


def _measured(
    result: LocateSummary,
    rec: ChunkedRecording,
    sampled: list,
    out_dir: Path,
    say: Callable[[str], None],
) -> None:
    """For a bench's frames, out_dir/measured.csv: the strongest touch of each sample's
    frame, mm, and its samples into `result`; without bench samples, an earlier run's
    measured.csv is removed."""
    if rec.sample is not None:
        ids, pts = strongest_per_sample(TouchTable.concat(sampled), rec.sample)
        write_csv(
            out_dir / "measured.csv",
            POINT_HEADER,
            ([int(k), *map(float, p)] for k, p in zip(ids, pts, strict=True)),
            comments=["strongest touch of each bench sample's frame, mm"],
        )
        n_samples = int(np.unique(rec.sample[rec.sample >= 0]).size)
        result["measured_csv"] = str(out_dir / "measured.csv")
        result["samples"] = n_samples
        result["samples_missed"] = n_samples - int(ids.size)
        return
    if (out_dir / "measured.csv").exists():  # a bench run's, not of these frames
        (out_dir / "measured.csv").unlink()
        say(
            f"removed {out_dir / 'measured.csv'}: left by an earlier run (these frames have "
            "no bench samples)"
        )


def strongest_per_sample(table: TouchTable, sample: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sample ids (m,), points (m, 3) mm): the strongest touch of each sample's frame."""
    frame_sample = sample[table.frame]
    keep = frame_sample >= 0
    order = np.lexsort((-table.peak[keep], frame_sample[keep]))
    fs, xyz = frame_sample[keep][order], table.xyz_mm[keep][order]
    first = np.r_[True, fs[1:] != fs[:-1]] if fs.size else np.zeros(0, bool)
    ids, pts = fs[first], xyz[first]
    return ids, pts


def _usable_cpus() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _sample_touches(table: TouchTable, sample: np.ndarray) -> TouchTable:
    """The touches of `table` in bench sample frames (sample >= 0)."""
    return table.rows((sample[table.frame] >= 0) & (table.kind == TOUCH))
