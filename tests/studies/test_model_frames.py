"""The model method's number of frames, chosen on a calibration run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fruitcli.fsutil import write_csv
from fruitcli.studies import model_frames

TRUTH = np.array([[0.0, 0.0, 1.0], [10.0, 0.0, 1.0], [0.0, 10.0, 1.0], [10.0, 10.0, 1.0]])
HEADER = ["sample", "x_mm", "y_mm", "z_mm"]


def _run(tmp_path: Path, truth: np.ndarray = TRUTH) -> Path:
    run = tmp_path / "calibration"
    run.mkdir()
    write_csv(run / "truth.csv", HEADER, ([k, *p] for k, p in enumerate(truth)))
    (run / "frames.npz").write_bytes(b"")  # the fake locate does not read it
    return run


def _locator(errors_mm: dict[int, float], missing: int | None = None, calls: list | None = None):
    """A locate that places every sample but `missing` off by a rigid shift (which the
    translation registration removes) plus a spread of `errors_mm[frames]` mm."""
    spread = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])

    def locate(frames: int, bench: Path, folder: Path) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        placed = TRUTH + np.array([3.0, -2.0, 0.0]) + errors_mm[frames] * spread
        keep = [k for k in range(len(TRUTH)) if k != missing]
        write_csv(folder / "measured.csv", HEADER, ([k, *placed[k]] for k in keep))
        if calls is not None:
            calls.append((frames, bench.name))

    return locate


def test_the_setting_whose_registered_error_is_least_is_chosen(tmp_path):
    errors = {1: 2.0, 2: 1.5, 4: 0.5, 8: 0.75, 16: 1.0}
    calls: list = []
    chosen, tried, *_ = model_frames.choose(
        _locator(errors, calls=calls), _run(tmp_path), tmp_path / "frames"
    )
    assert chosen == 4
    assert tried == pytest.approx(errors, abs=1e-9)  # the shift registered away
    assert calls == [(k, "frames.npz") for k in model_frames.MODEL_FRAMES]


def test_a_tie_goes_to_fewer_frames(tmp_path):
    errors = {1: 2.0, 2: 0.5, 4: 0.5, 8: 0.5, 16: 0.5}
    choice = model_frames.choose(_locator(errors), _run(tmp_path), tmp_path / "frames")
    assert choice.frames == 2


def test_samples_without_a_touch_are_left_out_of_every_setting(tmp_path):
    errors = dict.fromkeys(model_frames.MODEL_FRAMES, 1.0)
    choice = model_frames.choose(_locator(errors, missing=3), _run(tmp_path), tmp_path / "f")
    assert (choice.counted, choice.found) == (3, 3)
    assert choice.samples_text() == "all its 3 samples"
    truth = (tmp_path / "f" / "16" / "truth.csv").read_text().splitlines()
    assert [line.split(",")[0] for line in truth[-3:]] == ["0", "1", "2"]
    # three samples off by (1, 0), (-1, 0), (0, 1) about their mean: registered error known
    placed = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]])
    expected = np.linalg.norm(placed - placed.mean(axis=0), axis=1).mean()
    assert choice.error_mm[16] == pytest.approx(expected, abs=1e-9)


def _inside_and_outside(tmp_path: Path, inside_count: int):
    """A calibration run with `inside_count` samples inside a 30 mm square of taxels,
    placed best with 4 frames, and one past it placed 20 mm off with 4 frames only; ->
    (locate, run, taxels, the errors inside)."""
    taxels = np.array([[0, 0, 0], [30, 0, 0], [0, 30, 0], [30, 30, 0]], float)
    inside = np.array([[5, 5, 0], [15, 5, 0], [25, 5, 0], [5, 25, 0], [15, 25, 0], [25, 25, 0]])
    truth = np.vstack([inside[:inside_count], [[40.0, 15.0, 0.0]]]).astype(float)
    spread = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [1, 0, 0], [-1, 0, 0]])
    spread = spread[:inside_count] - spread[:inside_count].mean(axis=0)
    errors = {1: 2.0, 2: 1.5, 4: 0.5, 8: 0.75, 16: 1.0}

    def locate(frames: int, bench: Path, folder: Path) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        placed = truth.copy()
        placed[:inside_count] += errors[frames] * spread
        placed[-1, 1] += 20.0 if frames == 4 else 0.0
        write_csv(folder / "measured.csv", HEADER, ([k, *p] for k, p in enumerate(placed)))

    return locate, _run(tmp_path, truth), taxels, errors


def test_samples_past_the_taxels_outline_do_not_tip_the_choice(tmp_path):
    """Six samples inside the taxels' outline, placed best with 4 frames; one past it,
    placed 20 mm off with 4 frames only: over all samples 8 frames win, over the samples
    inside 4 do."""
    locate, run, taxels, errors = _inside_and_outside(tmp_path, 6)
    assert model_frames.choose(locate, run, tmp_path / "all").frames == 8
    choice = model_frames.choose(locate, run, tmp_path / "in", outline_mm=taxels)
    assert choice.frames == 4
    assert choice.error_mm == pytest.approx(errors, abs=1e-9)  # the six, registered alone
    assert choice.samples_text() == "its 6 of 7 samples inside the taxels' outline"


@pytest.mark.parametrize("inside_count, frames", [(5, 4), (4, 8)])
def test_the_outline_counts_from_five_samples_inside(tmp_path, inside_count, frames):
    """With MIN_INSIDE (5) samples inside, they alone count; with one fewer, all do."""
    assert model_frames.MIN_INSIDE == 5
    locate, run, taxels, _ = _inside_and_outside(tmp_path, inside_count)
    choice = model_frames.choose(locate, run, tmp_path / "f", outline_mm=taxels)
    assert choice.frames == frames
    assert choice.counted == (inside_count if inside_count >= 5 else inside_count + 1)
