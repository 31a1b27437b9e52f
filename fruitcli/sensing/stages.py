"""Sensing stages as file-to-file functions: locate, bench and sensitivity.

Units: mm, counts, kPa, s. Each stage reads its inputs, calls the pure functions of
`fruitcli.sensing`, and writes its outputs atomically into `out_dir`.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.fsutil import write_csv
from fruitcli.geometry.body_surface import SurfaceProjector, body_surface, contact_heights
from fruitcli.scene import Scene, SkinSection, default_scene
from fruitcli.sensing.detection.frames_to_touches import (
    CHUNK_FRAMES,
    TOUCH,
    Locator,
    Settings,
    TouchTable,
)
from fruitcli.sensing.detection.locate import States, load_states, match_chambers
from fruitcli.sensing.detection.methods import METHODS
from fruitcli.sensing.detection.model_fit import FIT_MODEL
from fruitcli.sensing.frames.board import check_frame_shape
from fruitcli.sensing.frames.recording import Recording
from fruitcli.sensing.frames.recording_chunks import ChunkedRecording, open_recording
from fruitcli.sensing.outputs.touch_csv import touch_bytes, touch_csv
from fruitcli.sensing.skin.models import SKIN_MODELS
from fruitcli.tables import Taxels, read_taxels
from fruitcli.time_left import time_left

if TYPE_CHECKING:
    from fruitcli.sensing.skin.crossing_heights import CrossingHeights
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin
    from fruitcli.sensing.skin.heights import GapLaw

POINT_HEADER = ["sample", "x_mm", "y_mm", "z_mm"]


def _or_defaults(scene: Scene | None) -> Scene:
    """The scene, or without one a scene at the schema's defaults."""
    return default_scene() if scene is None else scene


def build_locator(
    scene,
    taxels: Taxels,
    states: States | None,
    rec: ChunkedRecording,
    settings: Settings,
    where: str,
    reduced=None,
    gain: np.ndarray | None = None,
    heights=None,
) -> tuple[Locator, np.ndarray | None]:
    """The Locator for a recording: rest positions, one state (meta "state", default 0)
    or the state path when the recording carries chamber pressures; with `reduced` (a
    ReducedModel of these taxels) and pressures in the recording, each frame's taxels
    from the reduced model at its pressures; `gain` (T,): the gains detection divides
    by (None: off); `heights`: the skin's height model (`Locator`). -> (locator,
    pressure)."""
    board = _or_defaults(scene).board
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
                gain,
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


def strongest_per_sample(table: TouchTable, sample: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sample ids (m,), points (m, 3) mm): the strongest touch of each sample's frame."""
    frame_sample = sample[table.frame]
    keep = frame_sample >= 0
    order = np.lexsort((-table.peak[keep], frame_sample[keep]))
    fs, xyz = frame_sample[keep][order], table.xyz_mm[keep][order]
    first = np.r_[True, fs[1:] != fs[:-1]] if fs.size else np.zeros(0, bool)
    ids, pts = fs[first], xyz[first]
    return ids, pts


def locator_taxels(states, state: int | None, taxels: Taxels) -> np.ndarray:
    """Taxel positions (T, 3) mm of the recording's state (rest without states)."""
    return taxels.xyz_mm if states is None else states.taxels_mm[state]


def surface_projector(
    scene, rec, states, pressure, taxels, surface_path, surface_unit, where: str, method=None
) -> SurfaceProjector | None:
    """The `SurfaceProjector` of ``[detection].project = "surface"``, or of the model
    method (its fitted points go onto the body's surface when the surface is known and
    the recording stays at one state); None otherwise."""
    detection = _or_defaults(scene).detection
    if detection.project != "surface":
        method = detection.method if method is None else method
        if not (model_on_surface(method) and surface_path and pressure is None):
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
        body_surface(surface_path, surface_unit),
        states,
        state,
        locator_taxels(states, state, taxels),
    )


def model_on_surface(method: str) -> bool:
    """Whether `method` places its touches on the body's surface when it is known."""
    return METHODS[method].refine == "model"


def run_locate(
    scene,
    frames_path,
    taxels_csv,
    states_npz_or_none,
    out_dir,
    progress=None,
    baseline_frames: int | None = None,
    threshold_counts: float | None = None,
    method: str | None = None,
    surface_path=None,
    surface_unit: str = "mm",
    chunk_frames: int = CHUNK_FRAMES,
    workers: int | None = None,
    reduced=None,
    gains_csv=None,
    skin_table: SkinSection | None = None,
    hovers: bool | None = None,
    crossing_dir=None,
) -> dict:
    """Detect and locate every frame of a recording; write touches.csv (+ measured.csv).
    The recording is read, detected and written `chunk_frames` frames at a time, on
    `workers` threads (default: the CPUs this process may use, at most 4). With
    ``[detection].project = "surface"`` the located points are moved to the nearest
    point of the body's surface (`surface_path`, at rest, in `surface_unit`; carried by
    the recording's FEM state). With `reduced` (a ReducedModel), a recording with
    chamber pressures takes each frame's taxels from it (`build_locator`). Activations
    are divided by the taxels' gains with `gains_csv` or the scene's
    ``[detection].divide_by_gain`` (`gain_division`). Heights, strengths and sizes
    come from `skin_table` (a [skin] table, e.g. `fruit calibrate`'s) or the scene's
    [skin] (`fruitcli.sensing.skin.heights.gap_law`; with ``[skin].model =
    "electrostatic"``, the crossing's table from `crossing_dir` or computed now,
    `crossing_heights`); hovers are written with kind hover and are never bench
    samples."""
    from fruitcli.sensing.detection.gain_division import detection_gain

    say = progress or (lambda msg: None)
    out_dir = Path(out_dir)
    taxels = read_taxels(taxels_csv, FrameError)
    board = _or_defaults(scene).board
    states = None if states_npz_or_none is None else load_states(states_npz_or_none, len(taxels))
    settings = Settings.from_scene(
        _or_defaults(scene).detection,
        baseline_frames=baseline_frames,
        threshold_counts=threshold_counts,
        method=method,
        hovers=hovers,
    )
    if settings.threshold_counts <= 0:
        raise FrameError(f"threshold: expected > 0 counts, got {settings.threshold_counts}")
    where = str(frames_path)
    gain = detection_gain(scene, taxels, gains_csv)
    crossing = None
    if skin_table is None and scene is not None:
        skin_table = scene.skin
        crossing = electrostatic_skin(scene, crossing_dir, say)
    heights = skin_heights(skin_table, taxels, settings, gain is not None, crossing)
    if workers is None:
        workers = min(4, _usable_cpus())
    with open_recording(frames_path, board.rows, board.cols, board.format, "read") as rec:
        locator, pressure = build_locator(
            scene, taxels, states, rec, settings, where, reduced, gain, heights
        )
        projector = surface_projector(
            scene, rec, states, pressure, taxels, surface_path, surface_unit, where, settings.method
        )
        if projector is not None:
            locator.use_surface(projector.verts, projector.tris)
        only_fitted = (
            settings.method == "model" and _or_defaults(scene).detection.project != "surface"
        )
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
        sampled, done, shown, first = [], 0, t0, None
        moved = [0, 0.0, 0.0]  # touches projected, sum and max of the distances (mm)

        def rows(table: TouchTable):  # in the worker thread
            dist = None
            if projector is not None:
                rows = slice(None)
                if only_fitted:  # the model's points; the N9 points it kept stay as they are
                    rows = np.flatnonzero(table.fit == FIT_MODEL)
                table.xyz_mm[rows], dist = projector.project(table.xyz_mm[rows])
            keep = None if rec.sample is None else _sample_touches(table, rec.sample)
            return touch_bytes(table, rec.t_s, model), len(table), keep, dist

        model = locator.model is not None
        with touch_csv(
            out_dir / "touches.csv",
            [
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
            ],
            model,
        ) as out:
            for data, count, keep, dist in locator.chunks(
                rec.read, len(rec), baseline, pressure, chunk_frames, rows, workers
            ):
                out.write(data, count)
                if keep is not None:
                    sampled.append(keep)
                if dist is not None and len(dist):
                    moved = [
                        moved[0] + len(dist),
                        moved[1] + float(dist.sum()),
                        max(moved[2], float(dist.max())),
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
        dt = time.perf_counter() - t0
    result = {
        "frames": len(rec),
        "touches": out.rows,
        "skipped_lines": rec.skipped_lines,
        "seconds": dt,
        "frames_per_s": len(rec) / max(dt, 1e-9),
        "touches_csv": str(out_dir / "touches.csv"),
    }
    if projector is not None:
        projected = {
            "touches": moved[0],
            "mean_mm": moved[1] / max(moved[0], 1),
            "max_mm": moved[2],
        }
        result["projected_to_surface"] = projected
        say(
            f"projected {moved[0]} touches onto the surface: moved "
            f"{projected['mean_mm']:.2f} mm on average, {projected['max_mm']:.2f} mm at most"
        )
    if pressure is not None and locator.reduced is not None:
        outside = int(locator.reduced.outside(pressure).sum())
        result["model"] = "reduced"
        result["frames_outside_reduced_range"] = outside
        say(
            f"taxels from the reduced model at each frame's pressures "
            f"({locator.reduced.describe()}); {outside} of {len(rec)} frames outside its "
            "range (clamped to it)"
        )
    elif pressure is not None:  # frames far from the simulated path: counted, not hidden
        from fruitcli.sensing.detection.pressure_path import report_off_path

        result["model"] = "full"

        result["pressure_path"] = report_off_path(
            rec, pressure, locator.state_pressure_kpa, out_dir, say
        )
    if rec.sample is not None:
        ids, pts = strongest_per_sample(TouchTable.concat(sampled), rec.sample)
        write_csv(
            out_dir / "measured.csv",
            POINT_HEADER,
            ([int(k), *map(float, p)] for k, p in zip(ids, pts, strict=True)),
            comments=["strongest touch of each bench sample's frame, mm"],
        )
        n_samples = int(np.unique(rec.sample[rec.sample >= 0]).size)
        result.update(
            measured_csv=str(out_dir / "measured.csv"),
            samples=n_samples,
            samples_missed=n_samples - int(ids.size),
        )
    elif (out_dir / "measured.csv").exists():  # a bench run's, not of these frames
        (out_dir / "measured.csv").unlink()
        say(
            f"removed {out_dir / 'measured.csv'}: left by an earlier run (these frames have "
            "no bench samples)"
        )
    say(f"{out.rows} touches, {result['frames_per_s']:.0f} frames/s")
    return result


def _usable_cpus() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _sample_touches(table: TouchTable, sample: np.ndarray) -> TouchTable:
    """The touches of `table` in bench sample frames (sample >= 0)."""
    return table.rows((sample[table.frame] >= 0) & (table.kind == TOUCH))


def skin_heights(
    skin: SkinSection | None, taxels: Taxels, settings: Settings, divided: bool, crossing=None
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


def _sample_points(scene, taxels_mm: np.ndarray) -> np.ndarray:
    """(x, y) mm of the bench samples: "quarter" or a CSV (sample,x_mm,y_mm)."""
    from fruitcli.sensing.skin.virtual_bench import quarter_samples
    from fruitcli.tables import read_table

    spec = scene.bench.samples
    if spec == "quarter":
        g = scene.grid
        return quarter_samples(taxels_mm[:, :2], g.spacing_x_mm, g.spacing_y_mm)
    from fruitcli.scene import resolve_path

    cols = read_table(resolve_path(scene.path, spec), ["x_mm", "y_mm"], error=FrameError)
    return np.stack([cols["x_mm"], cols["y_mm"]], axis=1)


def electrostatic_skin(scene, crossing_dir, progress=None) -> CrossingSkin | None:
    """The crossing's table in counts with ``[skin].model = "electrostatic"`` (from
    `crossing_dir`, the skin stage's folder, or computed now without one), else None."""
    if not SKIN_MODELS[_or_defaults(scene).skin.model].computed:
        return None
    from fruitcli.sensing.skin.crossing_skin import crossing_skin

    return crossing_skin(scene, crossing_dir, progress)


def run_bench(
    scene,
    taxels_csv,
    states_npz_or_none,
    out_dir,
    progress=None,
    surface_path=None,
    surface_unit: str = "mm",
    crossing_dir=None,
) -> dict:
    """Virtual 3D-printer bench: per indenter, out_dir/<indenter>/frames.npz + truth.csv.
    `surface_path`: the body's closed surface at rest (the ground truth's surface; see
    `fruitcli.sensing.skin.virtual_bench`), in `surface_unit`. With ``[skin].model =
    "electrostatic"`` the taxels' activation and baseline shift come from the crossing's
    table in `crossing_dir` (`electrostatic_skin`)."""
    from fruitcli.sensing.frames.board import taxel_cells
    from fruitcli.sensing.frames.recording import write_npz
    from fruitcli.sensing.skin import forward
    from fruitcli.sensing.skin.virtual_bench import BENCH_FPS, bench_bytes, cell_counts, descend

    say = progress or (lambda msg: None)
    out_dir = Path(out_dir)
    taxels = read_taxels(taxels_csv, FrameError)
    board, bench = scene.board, scene.bench
    threshold = scene.detection.threshold_counts
    rows, cols = taxel_cells(taxels, board, str(taxels_csv))
    from fruitcli.memory import require

    # idle frames: counts and their noise per taxel (float), then board frames (float, uint16)
    require(
        bench.baseline_frames * (3 * 8 * len(taxels) + 10 * board.rows * board.cols),
        f"{scene.path.name}: [bench].baseline_frames = {bench.baseline_frames}",
        FrameError,
    )
    state = bench.state
    skin = forward.make_skin(
        len(taxels), bench.seed, forward.SkinParams.from_table(_or_defaults(scene).skin), taxels.ids
    )
    surface = None if surface_path is None else body_surface(surface_path, surface_unit)
    response = electrostatic_skin(scene, crossing_dir, progress)
    states = None
    if states_npz_or_none is not None:
        states = load_states(states_npz_or_none, len(taxels))
        if not 0 <= state < states.n_states:
            raise FrameError(
                f"{scene.path.name}: [bench].state: {state} not in the states "
                f"(0..{states.n_states - 1})"
            )
        taxels_mm = states.taxels_mm[state]
        if response is None:
            shift = forward.strain_shift_counts(forward.taxel_strain(states, state), skin)
        else:
            from fruitcli.sensing.skin.crossing_skin import shift_counts

            shift = shift_counts(states, response, skin.fab, state)
    else:
        if state != 0:
            raise FrameError(f"{scene.path.name}: [bench].state = {state} needs FEM states")
        taxels_mm = taxels.xyz_mm
        shift = np.zeros(len(taxels))
    xy = _sample_points(scene, taxels_mm)
    z, truth_surface = contact_heights(xy, taxels_mm, states, state, surface)
    on_surface = np.flatnonzero(np.isfinite(z))
    contact = np.column_stack([xy, z])[on_surface]
    say(
        f"{len(xy)} sample points, {len(contact)} of them over {truth_surface} "
        f"({len(xy) - len(contact)} outside it are left out)"
    )
    if len(contact) == 0:
        raise FrameError(
            f"{scene.path.name}: [bench].samples: none of the {len(xy)} sample "
            f"points lies over {truth_surface}; expected points (x, y) over the "
            "body"
        )
    require(
        bench_bytes(bench.step_mm, len(contact), len(taxels), board.rows * board.cols),
        f"{scene.path.name}: [bench].step_mm = {bench.step_mm:g} over {len(contact)} samples",
        FrameError,
    )
    result = {
        "samples": int(len(xy)),
        "off_surface": int(len(xy) - len(contact)),
        "truth_surface": truth_surface,
        "indenters": {},
    }
    for n, name in enumerate(bench.indenters):
        if response is None:
            forward.footprint_sigma_mm(name, skin.params)  # validates the name
        else:
            response.object_index(name)
        rng = np.random.default_rng([bench.seed, n])
        run = descend(
            contact,
            taxels_mm,
            skin.baseline_counts + shift,
            skin,
            name,
            bench.step_mm,
            bench.baseline_frames,
            threshold,
            rng,
            response,
        )
        if len(run.truth_ids) == 0:
            raise FrameError(
                f"{scene.path.name}: [bench]: no sample of the {name} indenter "
                f"reached [detection].threshold_counts = {threshold:g} counts; "
                "the bench has no touch to record"
            )
        n_frames = run.counts.shape[0]
        fill = forward.frame_counts(
            np.full((n_frames, board.rows, board.cols), forward.BASELINE_COUNTS),
            np.median(skin.noise_std_counts),
            rng,
        )
        frames = cell_counts(run.counts, rows, cols, (board.rows, board.cols), fill)
        meta = {
            "source": "bench",
            "scene": scene.name,
            "indenter": name,
            "state": state,
            "seed": bench.seed,
            "step_mm": bench.step_mm,
            "threshold_counts": threshold,
            "baseline_frames": bench.baseline_frames,
            "fps": BENCH_FPS,
        }
        rec = Recording(frames, np.arange(n_frames) / BENCH_FPS, sample=run.sample, meta=meta)
        write_npz(out_dir / name / "frames.npz", rec)
        write_csv(
            out_dir / name / "truth.csv",
            POINT_HEADER,
            ([int(k), *map(float, p)] for k, p in zip(run.truth_ids, run.truth_mm, strict=True)),
            comments=[
                f"bench contact points ({name} indenter, state {state}), mm, on {truth_surface}"
            ],
        )
        result["indenters"][name] = {
            "frames": n_frames,
            "samples": int(len(run.truth_ids)),
            "dropped": run.dropped,
        }
        say(f"{name}: {len(run.truth_ids)} samples, {n_frames} frames")
    return result


def _box_outline(xy_mm: np.ndarray, pad_mm: float = 8.0) -> np.ndarray:
    """Two triangles (2, 3, 2) covering the taxels' bounding box grown by `pad_mm` (mm)."""
    (x0, y0), (x1, y1) = xy_mm.min(axis=0) - pad_mm, xy_mm.max(axis=0) + pad_mm
    return np.array([[[x0, y0], [x1, y0], [x1, y1]], [[x0, y0], [x1, y1], [x0, y1]]])


def run_sensitivity(
    scene, taxels_csv, states_npz, out_dir, progress=None, crossing_dir=None
) -> dict:
    """Noise std per taxel at rest and max baseline shift per taxel over the states' animation
    (Figs. 10, 11; Fig. 9 for a bent pad): sensitivity.json, noise_std.png, max_shift.png.
    With ``[skin].model = "electrostatic"`` the shifts come from the crossing's table in
    `crossing_dir` (`electrostatic_skin`)."""
    from fruitcli.fsutil import write_json
    from fruitcli.sensing.skin import forward, sensitivity
    from fruitcli.sensing.skin.heat_maps import save_heatmap, save_topview

    say = progress or (lambda msg: None)
    out_dir = Path(out_dir)
    taxels = read_taxels(taxels_csv, FrameError)
    states = None if states_npz is None else load_states(states_npz, len(taxels))
    sens = scene.sensitivity
    from fruitcli.memory import require

    # frames at rest, then the animation's: noise, mean and counts per taxel (float, int)
    for key, frames in (
        ("noise_frames", sens.noise_frames),
        ("animation_frames", sens.animation_frames),
    ):
        require(
            frames * len(taxels) * 8.0 * 4,
            f"{scene.path.name}: [sensitivity].{key} = {frames} over {len(taxels)} taxels",
            FrameError,
        )
    skin = forward.make_skin(
        len(taxels),
        scene.bench.seed,
        forward.SkinParams.from_table(_or_defaults(scene).skin),
        taxels.ids,
    )
    rng = np.random.default_rng([scene.bench.seed, 99])
    rest = forward.frame_counts(
        np.broadcast_to(skin.baseline_counts, (sens.noise_frames, len(taxels))),
        skin.noise_std_counts,
        rng,
    )
    std = sensitivity.noise_std_counts(rest)
    # no deformation (no FEM): one state, the taxels at rest, no strain
    strain = np.zeros((1, len(taxels))) if states is None else forward.taxel_strain(states)
    response = electrostatic_skin(scene, crossing_dir, progress)
    if response is None:
        gain = forward.calibrate_strain_gain()
        shift_model = forward.strain_shift_counts(strain, skin, gain)
    else:
        from fruitcli.sensing.skin.crossing_skin import shift_counts

        gain = None
        shift_model = (
            np.zeros_like(strain) if states is None else shift_counts(states, response, skin.fab)
        )
    anim = sensitivity.animation_shift(shift_model, sens.animation_frames)
    played = forward.frame_counts(skin.baseline_counts + anim, skin.noise_std_counts, rng)
    shift = sensitivity.max_shift_counts(played, rest.mean(axis=0))
    model_max = shift_model.max(axis=0)
    threshold = scene.detection.threshold_counts
    taxel_rows = [
        {
            "id": int(taxels.ids[k]),
            "i": int(taxels.i[k]),
            "j": int(taxels.j[k]),
            "std": float(std[k]),
            "max_shift": float(shift[k]),
            "max_shift_model": float(model_max[k]),
            "strain_max": float(strain[:, k].max()),
            "fab": float(skin.fab[k]),
        }
        for k in range(len(taxels))
    ]
    out = {
        "units": "counts (strain: Green-Lagrange norm, -)",
        "threshold_counts": threshold,
        "noise_frames": sens.noise_frames,
        "animation_frames": sens.animation_frames,
        "states": len(strain),
        "strain_gain_counts": gain,
        **(
            {}
            if response is None
            else {"skin_model": "electrostatic", "counts_per_ff": response.counts_per_ff}
        ),
        "summary": {
            "std": sensitivity.summary(std),
            "max_shift": sensitivity.summary(shift),
            "max_shift_model": sensitivity.summary(model_max),
        },
        "taxels": taxel_rows,
    }
    write_json(out_dir / "sensitivity.json", out)
    save_heatmap(
        out_dir / "noise_std.png",
        taxels.i,
        taxels.j,
        std,
        f"noise std over {sens.noise_frames} frames at rest",
        threshold / 2,
    )
    save_heatmap(
        out_dir / "max_shift.png",
        taxels.i,
        taxels.j,
        shift,
        "max baseline shift over the animation",
        threshold,
    )
    outline = (
        _box_outline(taxels.xyz_mm[:, :2])
        if states is None
        else states.rest_nodes[states.surface_tris][:, :, :2]
    )
    xy = taxels.xyz_mm[:, :2]
    save_topview(
        out_dir / "noise_std_top.png",
        xy,
        std,
        outline,
        f"noise std over {sens.noise_frames} frames at rest (top view, counts)",
        threshold / 2,
    )
    save_topview(
        out_dir / "max_shift_top.png",
        xy,
        shift,
        outline,
        "max baseline shift over the animation (top view, counts)",
        threshold,
    )
    say(
        f"noise std max {std.max():.2f}, max shift max {shift.max():.1f} "
        f"mean {shift.mean():.1f} counts"
    )
    return out
