"""Sensing stages as file-to-file functions: locate, bench and sensitivity.

Units: mm, counts, kPa, s. Each stage reads its inputs, calls the pure functions of
`fruitcli.sensing`, and writes its outputs atomically into `out_dir`.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.fsutil import write_csv
from fruitcli.sensing.board import Taxels, check_frame_shape, load_taxels
from fruitcli.sensing.frames_io import Recording
from fruitcli.sensing.locate import States, load_states, match_chambers
from fruitcli.sensing.pipeline import CHUNK_FRAMES, Locator, Settings, TouchTable
from fruitcli.sensing.recording_chunks import ChunkedRecording, open_recording
from fruitcli.sensing.touch_csv import touch_bytes, touch_csv

POINT_HEADER = ["sample", "x_mm", "y_mm", "z_mm"]


def _section(scene, name: str) -> dict:
    if scene is None:
        from fruitcli.scene import SCHEMA

        return {k: spec.default for k, spec in SCHEMA[name].items()}
    return scene[name]


def build_locator(scene, taxels: Taxels, states: States | None, rec: ChunkedRecording,
                  settings: Settings, where: str) -> tuple[Locator, np.ndarray | None]:
    """The Locator for a recording: rest positions, one state (meta "state", default 0)
    or the state path when the recording carries chamber pressures. -> (locator, pressure)."""
    board = _section(scene, "board")
    check_frame_shape(np.empty((0, *rec.frame_shape)), board, where)
    if states is None:
        return Locator(taxels, board, taxels.xyz_mm, settings, where=where), None
    if rec.pressure_kpa is not None and states.n_states > 1:
        cols = match_chambers(rec.chamber_names, states, where)
        return (Locator(taxels, board, states.taxels_mm, settings, states.pressure_kpa, where),
                rec.pressure_kpa[:, cols])
    state = int(rec.meta.get("state", 0))
    if not 0 <= state < states.n_states:
        raise FrameError(f"{where}: meta state {state} not in the states "
                         f"(0..{states.n_states - 1})")
    return Locator(taxels, board, states.taxels_mm[state], settings, where=where), None


def strongest_per_sample(table: TouchTable, sample: np.ndarray) -> tuple[np.ndarray,
                                                                         np.ndarray]:
    """(sample ids (m,), points (m, 3) mm): the strongest touch of each sample's frame."""
    frame_sample = sample[table.frame]
    keep = frame_sample >= 0
    order = np.lexsort((-table.peak[keep], frame_sample[keep]))
    fs, xyz = frame_sample[keep][order], table.xyz_mm[keep][order]
    first = np.r_[True, fs[1:] != fs[:-1]] if fs.size else np.zeros(0, bool)
    ids, pts = fs[first], xyz[first]
    return ids, pts


def run_locate(scene, frames_path, taxels_csv, states_npz_or_none, out_dir,
               progress=None, baseline_frames: int | None = None,
               threshold_counts: float | None = None, method: str | None = None,
               chunk_frames: int = CHUNK_FRAMES, workers: int | None = None) -> dict:
    """Detect and locate every frame of a recording; write touches.csv (+ measured.csv).
    The recording is read, detected and written `chunk_frames` frames at a time, on
    `workers` threads (default: the CPUs this process may use, at most 4)."""
    say = progress or (lambda msg: None)
    out_dir = Path(out_dir)
    taxels = load_taxels(taxels_csv)
    board = _section(scene, "board")
    states = None if states_npz_or_none is None else load_states(states_npz_or_none,
                                                                 len(taxels))
    settings = Settings.from_scene(_section(scene, "detection"),
                                   baseline_frames=baseline_frames,
                                   threshold_counts=threshold_counts, method=method)
    if settings.threshold_counts <= 0:
        raise FrameError(f"threshold: expected > 0 counts, got {settings.threshold_counts}")
    where = str(frames_path)
    if workers is None:
        workers = min(4, _usable_cpus())
    with open_recording(frames_path, board["rows"], board["cols"]) as rec:
        locator, pressure = build_locator(scene, taxels, states, rec, settings, where)
        say(f"{len(rec)} frames, {len(taxels)} taxels, {rec.skipped_lines} lines skipped")
        t0 = time.perf_counter()
        baseline = locator.baseline(rec.read(0, settings.baseline_frames), where, len(rec))
        sampled, done, shown = [], 0, t0

        def rows(table: TouchTable):  # in the worker thread
            keep = None if rec.sample is None else _sample_touches(table, rec.sample)
            return touch_bytes(table, rec.t_s), len(table), keep

        with touch_csv(out_dir / "touches.csv",
                       [f"touches of {Path(frames_path).name}: frame index from 0 "
                        "(baseline frames included), t_s in s, i, j fractional grid "
                        "coordinates, x_mm, y_mm, z_mm in mm, peak in counts"]) as out:
            for data, count, keep in locator.chunks(rec.read, len(rec), baseline, pressure,
                                                    chunk_frames, rows, workers):
                out.write(data, count)
                if keep is not None:
                    sampled.append(keep)
                done = min(done + chunk_frames, len(rec))
                if time.perf_counter() - shown > 2.0:
                    shown = time.perf_counter()
                    say(f"{done} of {len(rec)} frames, {out.rows} touches")
        dt = time.perf_counter() - t0
    result = {"frames": len(rec), "touches": out.rows, "skipped_lines": rec.skipped_lines,
              "seconds": dt, "frames_per_s": len(rec) / max(dt, 1e-9),
              "touches_csv": str(out_dir / "touches.csv")}
    if rec.sample is not None:
        ids, pts = strongest_per_sample(TouchTable.concat(sampled), rec.sample)
        write_csv(out_dir / "measured.csv", POINT_HEADER,
                  ([int(k), *map(float, p)] for k, p in zip(ids, pts, strict=True)),
                  comments=["strongest touch of each bench sample's frame, mm"])
        n_samples = int(np.unique(rec.sample[rec.sample >= 0]).size)
        result.update(measured_csv=str(out_dir / "measured.csv"), samples=n_samples,
                      samples_missed=n_samples - int(ids.size))
    say(f"{out.rows} touches, {result['frames_per_s']:.0f} frames/s")
    return result


def _usable_cpus() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _sample_touches(table: TouchTable, sample: np.ndarray) -> TouchTable:
    """The touches of `table` in bench sample frames (sample >= 0)."""
    keep = sample[table.frame] >= 0
    return TouchTable(table.frame[keep], table.touch[keep], table.i[keep], table.j[keep],
                      table.xyz_mm[keep], table.peak[keep])


def _sample_points(scene, taxels_mm: np.ndarray) -> np.ndarray:
    """(x, y) mm of the bench samples: "quarter" or a CSV (sample,x_mm,y_mm)."""
    from fruitcli.sensing.bench import quarter_samples
    from fruitcli.tables import read_table

    spec = scene["bench"]["samples"]
    if spec == "quarter":
        g = scene["grid"]
        return quarter_samples(taxels_mm[:, :2], g["spacing_x_mm"], g["spacing_y_mm"])
    from fruitcli.scene import resolve_path

    cols = read_table(resolve_path(scene.path, spec), ["x_mm", "y_mm"], error=FrameError)
    return np.stack([cols["x_mm"], cols["y_mm"]], axis=1)


def run_bench(scene, taxels_csv, states_npz_or_none, out_dir, progress=None) -> dict:
    """Virtual 3D-printer bench: per indenter, out_dir/<indenter>/frames.npz + truth.csv."""
    from fruitcli.sensing import forward
    from fruitcli.sensing.bench import (
        BENCH_FPS,
        cell_counts,
        descend,
        surface_heights,
        taxel_surface_heights,
    )
    from fruitcli.sensing.board import taxel_cells
    from fruitcli.sensing.frames_io import write_npz

    say = progress or (lambda msg: None)
    out_dir = Path(out_dir)
    taxels = load_taxels(taxels_csv)
    board, bench = scene["board"], scene["bench"]
    threshold = scene["detection"]["threshold_counts"]
    rows, cols = taxel_cells(taxels, board, str(taxels_csv))
    state = bench["state"]
    skin = forward.make_skin(len(taxels), bench["seed"])
    if states_npz_or_none is not None:
        states = load_states(states_npz_or_none, len(taxels))
        if not 0 <= state < states.n_states:
            raise FrameError(f"{scene.path.name}: [bench].state: {state} not in the states "
                             f"(0..{states.n_states - 1})")
        taxels_mm = states.taxels_mm[state]
        xy = _sample_points(scene, taxels_mm)
        z = surface_heights(xy, states.nodes_mm(state), states.surface_tris)
        shift = forward.strain_shift_counts(forward.taxel_strain(states, state), skin)
    else:
        if state != 0:
            raise FrameError(f"{scene.path.name}: [bench].state = {state} needs FEM states")
        taxels_mm = taxels.xyz_mm
        xy = _sample_points(scene, taxels_mm)
        z = taxel_surface_heights(xy, taxels_mm)
        shift = np.zeros(len(taxels))
    on_surface = np.flatnonzero(np.isfinite(z))
    contact = np.column_stack([xy, z])[on_surface]
    say(f"{len(xy)} sample points, {len(contact)} of them over the taxels' surface "
        f"({len(xy) - len(contact)} outside it are left out)")
    result = {"samples": int(len(xy)), "off_surface": int(len(xy) - len(contact)),
              "indenters": {}}
    for n, name in enumerate(bench["indenters"]):
        forward.footprint_sigma_mm(name)  # validates the name
        rng = np.random.default_rng([bench["seed"], n])
        run = descend(contact, taxels_mm, skin.baseline_counts + shift, skin, name,
                      bench["step_mm"], bench["baseline_frames"], threshold, rng)
        n_frames = run.counts.shape[0]
        fill = forward.frame_counts(np.full((n_frames, board["rows"], board["cols"]),
                                            forward.BASELINE_COUNTS),
                                    np.median(skin.noise_std_counts), rng)
        frames = cell_counts(run.counts, rows, cols, (board["rows"], board["cols"]), fill)
        meta = {"source": "bench", "scene": scene.name, "indenter": name, "state": state,
                "seed": bench["seed"], "step_mm": bench["step_mm"],
                "threshold_counts": threshold, "baseline_frames": bench["baseline_frames"],
                "fps": BENCH_FPS}
        rec = Recording(frames, np.arange(n_frames) / BENCH_FPS, sample=run.sample, meta=meta)
        write_npz(out_dir / name / "frames.npz", rec)
        write_csv(out_dir / name / "truth.csv", POINT_HEADER,
                  ([int(k), *map(float, p)] for k, p in zip(run.truth_ids, run.truth_mm,
                                                             strict=True)),
                  comments=[f"bench contact points ({name} indenter, state {state}), mm"])
        result["indenters"][name] = {"frames": n_frames, "samples": int(len(run.truth_ids)),
                                     "dropped": run.dropped}
        say(f"{name}: {len(run.truth_ids)} samples, {n_frames} frames")
    return result


def run_sensitivity(scene, taxels_csv, states_npz, out_dir, progress=None) -> dict:
    """Noise std per taxel at rest and max baseline shift per taxel over the states' animation
    (Figs. 10, 11; Fig. 9 for a bent pad): sensitivity.json, noise_std.png, max_shift.png."""
    from fruitcli.fsutil import write_json
    from fruitcli.sensing import forward, sensitivity
    from fruitcli.sensing.plots import save_heatmap

    say = progress or (lambda msg: None)
    out_dir = Path(out_dir)
    taxels = load_taxels(taxels_csv)
    states = load_states(states_npz, len(taxels))
    sens = scene["sensitivity"]
    skin = forward.make_skin(len(taxels), scene["bench"]["seed"])
    rng = np.random.default_rng([scene["bench"]["seed"], 99])
    rest = forward.frame_counts(np.broadcast_to(skin.baseline_counts,
                                                (sens["noise_frames"], len(taxels))),
                                skin.noise_std_counts, rng)
    std = sensitivity.noise_std_counts(rest)
    strain = forward.taxel_strain(states)  # (S, T)
    gain = forward.calibrate_strain_gain()
    shift_model = forward.strain_shift_counts(strain, skin, gain)
    anim = sensitivity.animation_shift(shift_model, sens["animation_frames"])
    played = forward.frame_counts(skin.baseline_counts + anim, skin.noise_std_counts, rng)
    shift = sensitivity.max_shift_counts(played, rest.mean(axis=0))
    model_max = shift_model.max(axis=0)
    threshold = scene["detection"]["threshold_counts"]
    taxel_rows = [{"id": int(taxels.ids[k]), "i": int(taxels.i[k]), "j": int(taxels.j[k]),
                   "std": float(std[k]), "max_shift": float(shift[k]),
                   "max_shift_model": float(model_max[k]), "strain_max": float(strain[:, k].max()),
                   "fab": float(skin.fab[k])} for k in range(len(taxels))]
    out = {"units": "counts (strain: Green-Lagrange norm, -)", "threshold_counts": threshold,
           "noise_frames": sens["noise_frames"], "animation_frames": sens["animation_frames"],
           "states": states.n_states, "strain_gain_counts": gain,
           "summary": {"std": sensitivity.summary(std), "max_shift": sensitivity.summary(shift),
                       "max_shift_model": sensitivity.summary(model_max)},
           "taxels": taxel_rows}
    write_json(out_dir / "sensitivity.json", out)
    save_heatmap(out_dir / "noise_std.png", taxels.i, taxels.j, std,
                 f"noise std over {sens['noise_frames']} frames at rest", threshold / 2)
    save_heatmap(out_dir / "max_shift.png", taxels.i, taxels.j, shift,
                 "max baseline shift over the animation", threshold)
    say(f"noise std max {std.max():.2f}, max shift max {shift.max():.1f} "
        f"mean {shift.mean():.1f} counts")
    return out
