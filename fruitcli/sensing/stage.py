"""Sensing stages as file-to-file functions: locate, bench and sensitivity.

Units: mm, counts, kPa, s. Each stage reads its inputs, calls the pure functions of
`fruitcli.sensing`, and writes its outputs atomically into `out_dir`.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.fsutil import write_csv
from fruitcli.sensing.board import Taxels, check_frame_shape, load_taxels
from fruitcli.sensing.frames_io import Recording, read_recording
from fruitcli.sensing.locate import States, load_states, match_chambers
from fruitcli.sensing.pipeline import Locator, Settings, TouchTable

TOUCH_HEADER = ["frame", "t_s", "touch", "i", "j", "x_mm", "y_mm", "z_mm", "peak"]
POINT_HEADER = ["sample", "x_mm", "y_mm", "z_mm"]


def _section(scene, name: str) -> dict:
    if scene is None:
        from fruitcli.scene import SCHEMA

        return {k: spec.default for k, spec in SCHEMA[name].items()}
    return scene[name]


def build_locator(scene, taxels: Taxels, states: States | None, rec: Recording,
                  settings: Settings, where: str) -> tuple[Locator, np.ndarray | None]:
    """The Locator for a recording: rest positions, one state (meta "state", default 0)
    or the state path when the recording carries chamber pressures. -> (locator, pressure)."""
    board = _section(scene, "board")
    check_frame_shape(rec.frames, board, where)
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


def touch_rows(table: TouchTable, t_s: np.ndarray):
    """Rows of touches.csv."""
    for n in range(len(table)):
        f = int(table.frame[n])
        x, y, z = table.xyz_mm[n]
        yield [f, float(t_s[f]), int(table.touch[n]), float(table.i[n]), float(table.j[n]),
               float(x), float(y), float(z), float(table.peak[n])]


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
               threshold_counts: float | None = None, method: str | None = None) -> dict:
    """Detect and locate every frame of a recording; write touches.csv (+ measured.csv)."""
    say = progress or (lambda msg: None)
    out_dir = Path(out_dir)
    taxels = load_taxels(taxels_csv)
    board = _section(scene, "board")
    rec = read_recording(frames_path, board["rows"], board["cols"])
    states = None if states_npz_or_none is None else load_states(states_npz_or_none,
                                                                 len(taxels))
    settings = Settings.from_scene(_section(scene, "detection"),
                                   baseline_frames=baseline_frames,
                                   threshold_counts=threshold_counts, method=method)
    if settings.threshold_counts <= 0:
        raise FrameError(f"threshold: expected > 0 counts, got {settings.threshold_counts}")
    where = str(frames_path)
    locator, pressure = build_locator(scene, taxels, states, rec, settings, where)
    say(f"{len(rec)} frames, {len(taxels)} taxels, {rec.skipped_lines} lines skipped")
    t0 = time.perf_counter()
    baseline = locator.baseline(rec.frames, where)
    table = locator.batch(rec.frames, baseline, pressure)
    dt = time.perf_counter() - t0
    write_csv(out_dir / "touches.csv", TOUCH_HEADER, touch_rows(table, rec.t_s),
              comments=[f"touches of {Path(frames_path).name}: frame index from 0 "
                        "(baseline frames included), t_s in s, i, j fractional grid "
                        "coordinates, x_mm, y_mm, z_mm in mm, peak in counts"])
    result = {"frames": len(rec), "touches": len(table), "skipped_lines": rec.skipped_lines,
              "seconds": dt, "frames_per_s": len(rec) / max(dt, 1e-9),
              "touches_csv": str(out_dir / "touches.csv")}
    if rec.sample is not None:
        ids, pts = strongest_per_sample(table, rec.sample)
        write_csv(out_dir / "measured.csv", POINT_HEADER,
                  ([int(k), *map(float, p)] for k, p in zip(ids, pts, strict=True)),
                  comments=["strongest touch of each bench sample's frame, mm"])
        n_samples = int(np.unique(rec.sample[rec.sample >= 0]).size)
        result.update(measured_csv=str(out_dir / "measured.csv"), samples=n_samples,
                      samples_missed=n_samples - int(ids.size))
    say(f"{len(table)} touches, {result['frames_per_s']:.0f} frames/s")
    return result
