"""The footprint's width from a recording's touches alone, without ground truth (`fruit
calibrate` without ``--truth``).

Units: mm, counts.

One touch's few taxels trade the footprint's width against the touch's position, so the
model method holds each touch's width near the skin's (`model_fit.WIDTH_PRIOR`), and a
skin width that is not the board's moves every touch: on the study's flat pad, boards
15 % narrower and wider than the skin assumes leave the model at 0.63-0.71 times N9's
error. The fits' own width scales do not show it (their median stays within 10 % of
1). Over a whole recording, though, the model explains the touches best near the
board's width. So every touch of the recording is fitted (on the mean of up to
``SCAN_FRAMES`` frames that show it, `model_fit.recent_frames`) at one common width
scale, held there (a prior of ``HELD_PRIOR``), for each scale of ``SCALES``; the scale
whose fits have the least mean reduced chi^2, refined by the parabola through it and
its neighbours, is the recording's.

A board wider than the skin assumes is found to a few per cent: its taxels a pitch away
read more than a narrower footprint allows anywhere. A narrower board is found only
part of the way from the skin's width towards its own: there a too-wide footprint
differs from the board's only on taxels that read below the noise, so the fits cannot
tell the widths between apart (on a 16 mm pitch with noise of 1.2 counts, a board of
5.0 mm against the skin's 6.2 mm gives 5.4-5.7 mm). Only the Gaussian law's width is
found so (a [skin] table holds it); the crossing table's width is the table's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError

if TYPE_CHECKING:
    from fruitcli.scene import Scene
    from fruitcli.sensing.detection.frames_to_touches import Locator

SCALES = np.round(np.arange(0.6, 1.6001, 0.05), 2)  # width scales tried (of the skin's)
HELD_PRIOR = 0.01  # a touch's width scale held to the common one within this (1-sigma)
MIN_TOUCHES = 10  # touches a width needs at least
SCAN_FRAMES = 8  # each touch fitted on the mean of its frame and up to 7 before it


@dataclass(frozen=True)
class TouchWidth:
    """The recording's width: `scale` times the skin's `skin_sigma_mm` (mm), the mean
    reduced chi^2 of the fits at each of `scales`, and how many touches were fitted."""

    scale: float
    skin_sigma_mm: float
    scales: np.ndarray
    chi2: np.ndarray
    touches: int

    @property
    def sigma_mm(self) -> float:
        """The footprint's width (mm) the touches fit best."""
        return self.scale * self.skin_sigma_mm


def touch_width(
    locator: Locator,
    read: Callable[[int, int], np.ndarray],
    n_frames: int,
    baseline: np.ndarray,
    where: str,
    pressure_kpa: np.ndarray | None = None,
) -> TouchWidth:
    """The width the model method's fits of every touch of a recording explain best:
    ``read(start, count)`` gives its frames (count, R, C), chunk by chunk, of `n_frames`
    (`locator`: the model method's, its baseline (T,) counts; `pressure_kpa` (N, K) the
    frames' chamber pressures or None). FrameError (naming `where`) with fewer than
    ``MIN_TOUCHES`` touches or a best width at the edge of ``SCALES``."""
    if locator.model is None:
        raise FrameError(f'{where}: the width from the touches needs [detection].method = "model"')
    window, law = locator.model
    chi2 = np.empty(len(SCALES))
    touches = 0
    try:
        for k, scale in enumerate(SCALES):
            locator.model = (window, law.scaled(float(scale), HELD_PRIOR))
            tables = locator.chunks(read, n_frames, baseline, pressure_kpa)
            red = np.concatenate([np.asarray(tb.residual, float) ** 2 for tb in tables])
            red = red[np.isfinite(red)]
            touches = red.size
            if touches < MIN_TOUCHES:
                raise FrameError(
                    f"{where}: {touches} touches the model could fit; the footprint's width "
                    f"from the touches needs at least {MIN_TOUCHES}"
                )
            chi2[k] = red.mean()
    finally:
        locator.model = (window, law)
    best = int(np.argmin(chi2))
    if best in (0, len(SCALES) - 1):
        raise FrameError(
            f"{where}: the touches fit best at {SCALES[best]:g} times the skin's footprint "
            f"width ({law.sigma_mm:.2f} mm), the edge of the widths tried "
            f"({SCALES[0]:g}-{SCALES[-1]:g}): set [skin].footprint_sigma_mm nearer the board's"
        )
    return TouchWidth(_vertex(SCALES, chi2, best), law.sigma_mm, SCALES.copy(), chi2, touches)


def _vertex(x: np.ndarray, y: np.ndarray, k: int) -> float:
    """The minimum of the parabola through (x, y) at k - 1, k, k + 1 (x[k] itself where
    it opens downward), kept within those neighbours."""
    a, b, _ = np.polyfit(x[k - 1 : k + 2], y[k - 1 : k + 2], 2)
    if a <= 0:
        return float(x[k])
    return float(np.clip(-b / (2 * a), x[k - 1], x[k + 1]))


def run_touch_width(
    scene: Scene,
    frames_path: str | Path,
    taxels_csv: str | Path,
    out_dir: str | Path,
    indenter: str | None = None,
    states_npz: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict:
    """`touch_width` of a recording located with `scene`'s [board], [detection] and [skin]
    (the model method, the footprint of `indenter` or the recording's meta); writes
    DIR/skin.toml (the scene's [skin] with that width and the recording's noise; no
    gains) and DIR/calibration.json, both or neither. -> the summary."""
    from fruitcli.fsutil import staged_dir, write_json, write_text
    from fruitcli.sensing.detection.gain_division import detection_gain
    from fruitcli.sensing.detection.locate import load_states
    from fruitcli.sensing.frames.recording_chunks import open_recording
    from fruitcli.sensing.inputs_stage import locate_inputs
    from fruitcli.sensing.locator_setup import build_locator, idle_settings, skin_heights
    from fruitcli.sensing.skin.calibrate import noise_std_counts
    from fruitcli.tables import read_taxels

    say = progress or (lambda msg: None)
    if scene.skin.model != "gaussian":
        raise FrameError(
            f'{scene.path}: [skin].model = "{scene.skin.model}": the width from the touches '
            "is the Gaussian law's; calibrate this skin with --truth"
        )
    where = str(frames_path)
    taxels = read_taxels(taxels_csv, FrameError)
    states = None if states_npz is None else load_states(states_npz, len(taxels))
    board = scene.board
    with open_recording(frames_path, board.rows, board.cols, board.format, "read") as rec:
        name = indenter or rec.meta.get("indenter")
        if not name:
            raise FrameError(f"{where}: meta names no indenter: give --indenter")
        keys = {
            "detection.method": "model",
            "detection.footprint": str(name),
            "detection.model_frames": SCAN_FRAMES,
        }
        inputs = locate_inputs(scene.with_values(keys))
        settings = idle_settings(inputs.settings, rec.meta, len(rec), where)
        gain = detection_gain(inputs.gain, taxels, inputs.gains_csv)
        heights = skin_heights(inputs.skin, taxels, settings, gain is not None)
        locator, pressure = build_locator(
            board, taxels, states, rec, settings, where, None, gain, heights
        )
        first = rec.read(0, settings.baseline_frames)
        baseline = locator.baseline(first, where, len(rec))
        n_frames = len(rec)
        say(f"{n_frames} frames: fitting every touch at {len(SCALES)} footprint widths")
        width = touch_width(locator, rec.read, n_frames, baseline, where, pressure)
    noise, _ = noise_std_counts(locator.values(first).astype(float))
    skin = scene.skin
    toml = (
        "# fruit calibrate: the footprint's width from a recording's touches (no ground "
        "truth); the rest is the scene's [skin]\n"
        "[skin]\n"
        f"footprint_sigma_mm = {{ {name} = {width.sigma_mm:.4f} }}\n"
        f"contact_counts = {skin.contact_counts:.4f}\n"
        f"gap_decay_mm = {skin.gap_decay_mm:.4f}\n"
        "gain_spread = 0.0\n"
        f"noise_std_counts = {noise:.4f}\n"
    )
    summary = {
        "indenter": str(name),
        "footprint_sigma_mm": width.sigma_mm,
        "scene_footprint_sigma_mm": width.skin_sigma_mm,
        "width_scale": width.scale,
        "touches": width.touches,
        "scales": width.scales.tolist(),
        "mean_reduced_chi2": width.chi2.tolist(),
        "noise_std_counts": noise,
        "frames": n_frames,
        "recording": where,
        "truth": None,
    }
    with staged_dir(out_dir) as tmp:
        write_text(tmp / "skin.toml", toml)
        write_json(tmp / "calibration.json", summary)
    say(
        f"{width.touches} touches fit best at {width.scale:.3f} times the scene's width: "
        f"{width.sigma_mm:.2f} mm"
    )
    return summary
