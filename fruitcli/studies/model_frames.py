"""How many frames' mean the model method fits (``[detection].model_frames``), chosen on
a calibration run: the setting of ``MODEL_FRAMES`` whose touches of that run land
nearest its truth (translation-registered mean error, mm; ties to fewer frames) over the
run's samples inside the taxels' outline (`evaluation.outline`) when at least
``MIN_INSIDE`` of them are, over all of them otherwise.

The bench's indenter is still in x and y while it descends, so the frames before the
threshold show the same touch and their mean has less noise; a live touch that moves
does not (`model_fit.recent_frames` takes only the frames since the touch's that point
the same way). A sample past the outline is placed only to within several millimetres
whatever the frames (`tests/performance/locate_bound.py`): its error swings by
millimetres from one setting to the next (a second fit's point taken or not), so the few
there can tip a close choice (`model-detection.md` has a case). The demo's model rows
(`fruitcli.workflow.model_rows`) and `fruit study locate`'s chosen row
(`fruitcli.studies.locate_methods`) both choose this way, on the run `calibrated_skin`
made, never on the frames they score.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np

MODEL_FRAMES = (1, 2, 4, 8, 16)
MIN_INSIDE = 5  # calibration samples inside the taxels' outline that the choice needs


class Choice(NamedTuple):
    """`choose`'s answer: the frames chosen, each setting's registered mean error (mm) over
    the samples counted, how many were counted and how many the run's touches found."""

    frames: int
    error_mm: dict[int, float]
    counted: int
    found: int

    def samples_text(self) -> str:
        """Which of the calibration run's samples the choice counted, for a report."""
        if self.counted < self.found:
            return f"its {self.counted} of {self.found} samples inside the taxels' outline"
        return f"all its {self.found} samples"


def choose(
    locate: Callable[[int, Path, Path], None],
    calibration: Path,
    work: Path,
    progress: Callable[[str], None] | None = None,
    outline_mm: np.ndarray | None = None,
) -> Choice:
    """The chosen number of frames, with the calibration run's registered mean error for
    each setting tried over the samples the choice counts (`Choice`). ``locate(frames,
    frames_npz, folder)`` locates a recording with the model method and that setting
    into folder (measured.csv, touches.csv); `calibration` holds the run's frames.npz
    and truth.csv; `work` gets a folder a setting; `outline_mm` (T, 3): the taxels in
    the run's state, whose outline picks the samples counted (None: all)."""
    from fruitcli.evaluation.outline import inside_outline, registered_mean
    from fruitcli.evaluation.report import evaluate_pair

    say = progress or (lambda msg: None)
    tried = {}
    counted = np.zeros(0, bool)
    for k in MODEL_FRAMES:
        say(f"the calibration run located with the mean of {k} frame(s)")
        folder = work / str(k)
        locate(k, calibration / "frames.npz", folder)
        truth = found_truth(calibration / "truth.csv", folder)
        result = evaluate_pair(truth, folder / "measured.csv", None, f"calibration, {k}")
        counted = np.ones(len(result[2]), bool)
        if outline_mm is not None:
            inside = inside_outline(result[2], outline_mm)
            counted = inside if inside.sum() >= MIN_INSIDE else counted
        tried[k] = registered_mean(result[2][counted], result[3][counted])
    best = min(tried, key=lambda k: (tried[k], k))
    return Choice(best, tried, int(counted.sum()), len(counted))


def found_truth(truth_csv: Path, folder: Path) -> Path:
    """FOLDER/truth.csv: the calibration run's truth rows of the samples the locate found
    a touch for (a sample whose peak ends on the threshold itself has none; which are
    found does not depend on the frames' mean, so every setting is scored on the same)."""
    from fruitcli.fsutil import write_csv
    from fruitcli.tables import read_table

    found = set(read_table(folder / "measured.csv", ["sample"])["sample"].astype(int).tolist())
    truth = read_table(truth_csv, ["sample", "x_mm", "y_mm", "z_mm"])
    keep = [k for k, s in enumerate(truth["sample"].astype(int)) if int(s) in found]
    out = folder / "truth.csv"
    write_csv(
        out,
        ["sample", "x_mm", "y_mm", "z_mm"],
        (
            [int(truth["sample"][k]), *(float(truth[c][k]) for c in ("x_mm", "y_mm", "z_mm"))]
            for k in keep
        ),
    )
    return out
