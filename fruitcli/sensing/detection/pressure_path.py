"""How far a recording's chamber pressures lie from the simulated states' path.

Units: kPa, s. The states are a path in pressure space (state 0 -> 1 -> ... -> S-1); a
frame's taxels are placed at the closest point of that path
(`fruitcli.sensing.detection.locate.state_path_position`). That is exact only for pressures on the
path; a frame whose pressures lie more than ``OFF_PATH_KPA`` from it (chambers driven
otherwise than simulated) is counted and reported with its distance, so it is not
mistaken for a modelled state.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.sensing.detection.locate import state_path_position

if TYPE_CHECKING:
    from fruitcli.sensing.frames.recording_chunks import ChunkedRecording

OFF_PATH_KPA = 0.5  # assumption: well above a pump sensor's noise, well below a state step


def path_distance_kpa(pressure_kpa: np.ndarray, state_pressure_kpa: np.ndarray) -> np.ndarray:
    """Euclidean distance (kPa) of each frame's pressures (N, K) to the state path (S, K)."""
    p = np.asarray(pressure_kpa, dtype=float)
    sp = np.asarray(state_pressure_kpa, dtype=float)
    seg, frac = state_path_position(p, sp)
    if sp.shape[0] == 1:
        nearest = np.broadcast_to(sp[0], p.shape)
    else:
        nearest = sp[seg] + frac[:, None] * (sp[seg + 1] - sp[seg])
    return np.linalg.norm(p - nearest, axis=1)


def off_path_summary(
    dist_kpa: np.ndarray, t_s: np.ndarray, no_reading: int = 0, tolerance_kpa: float = OFF_PATH_KPA
) -> dict:
    """Counts and the worst distance, for the locate result and its message."""
    off = np.flatnonzero(dist_kpa > tolerance_kpa)
    out = {
        "tolerance_kpa": tolerance_kpa,
        "frames_off_path": int(off.size),
        "max_distance_kpa": float(dist_kpa.max()) if dist_kpa.size else 0.0,
        "frames_without_pressure_reading": int(no_reading),
    }
    if off.size:
        worst = int(off[np.argmax(dist_kpa[off])])
        out.update(worst_frame=worst, worst_t_s=float(t_s[worst]), first_off_frame=int(off[0]))
    return out


def off_path_message(summary: dict, n_frames: int) -> str:
    """One line, e.g. "12 of 300 frames have pressures more than 0.5 kPa off the states'
    path (up to 3.2 kPa, frame 140): their taxels sit at the path's nearest point"."""
    parts = []
    k = summary["frames_off_path"]
    if k:
        parts.append(
            f"{k} of {n_frames} frames have pressures more than "
            f"{summary['tolerance_kpa']:g} kPa off the states' path (up to "
            f"{summary['max_distance_kpa']:.2f} kPa, frame {summary['worst_frame']}): "
            "their taxels sit at the path's nearest point, see off_path.csv"
        )
    else:
        parts.append(
            f"pressures within {summary['tolerance_kpa']:g} kPa of the states' path "
            f"(at most {summary['max_distance_kpa']:.2f} kPa)"
        )
    if summary["frames_without_pressure_reading"]:
        parts.append(
            f"{summary['frames_without_pressure_reading']} frames before the first "
            "pressure reading taken at 0 kPa"
        )
    return "; ".join(parts)


def report_off_path(
    rec: ChunkedRecording,
    pressure_kpa: np.ndarray,
    state_pressure_kpa: np.ndarray,
    out_dir: str | os.PathLike,
    say: Callable[[str], None] | None = None,
) -> dict:
    """Distances of a recording's frames to the state path: DIR/off_path.csv (frame, t_s,
    distance_kpa of every frame off the path), one progress line, and the summary."""
    from pathlib import Path

    from fruitcli.fsutil import write_csv

    dist = path_distance_kpa(pressure_kpa, state_pressure_kpa)
    no_reading = 0 if rec.pressure_t_s is None else int(np.isnan(rec.pressure_t_s).sum())
    summary = off_path_summary(dist, rec.t_s, no_reading)
    off = np.flatnonzero(dist > summary["tolerance_kpa"])
    write_csv(
        Path(out_dir) / "off_path.csv",
        ["frame", "t_s", "distance_kpa"],
        ([int(k), float(rec.t_s[k]), float(dist[k])] for k in off),
        comments=[
            f"frames whose chamber pressures lie more than "
            f"{summary['tolerance_kpa']:g} kPa from the simulated states' path "
            "(Euclidean, kPa); t_s in s"
        ],
    )
    if say:
        say(off_path_message(summary, len(rec)))
    return summary
