"""The model method's number of frames, chosen on a calibration run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fruitcli.fsutil import write_csv
from fruitcli.studies import model_frames

TRUTH = np.array([[0.0, 0.0, 1.0], [10.0, 0.0, 1.0], [0.0, 10.0, 1.0], [10.0, 10.0, 1.0]])
HEADER = ["sample", "x_mm", "y_mm", "z_mm"]


def _run(tmp_path: Path) -> Path:
    run = tmp_path / "calibration"
    run.mkdir()
    write_csv(run / "truth.csv", HEADER, ([k, *p] for k, p in enumerate(TRUTH)))
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
    chosen, tried = model_frames.choose(
        _locator(errors, calls=calls), _run(tmp_path), tmp_path / "frames"
    )
    assert chosen == 4
    assert tried == pytest.approx(errors, abs=1e-9)  # the shift registered away
    assert calls == [(k, "frames.npz") for k in model_frames.MODEL_FRAMES]


def test_a_tie_goes_to_fewer_frames(tmp_path):
    errors = {1: 2.0, 2: 0.5, 4: 0.5, 8: 0.5, 16: 0.5}
    chosen, _ = model_frames.choose(_locator(errors), _run(tmp_path), tmp_path / "frames")
    assert chosen == 2


def test_samples_without_a_touch_are_left_out_of_every_setting(tmp_path):
    errors = dict.fromkeys(model_frames.MODEL_FRAMES, 1.0)
    _, tried = model_frames.choose(_locator(errors, missing=3), _run(tmp_path), tmp_path / "f")
    truth = (tmp_path / "f" / "16" / "truth.csv").read_text().splitlines()
    assert [line.split(",")[0] for line in truth[-3:]] == ["0", "1", "2"]
    # three samples off by (1, 0), (-1, 0), (0, 1) about their mean: registered error known
    placed = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]])
    expected = np.linalg.norm(placed - placed.mean(axis=0), axis=1).mean()
    assert tried[16] == pytest.approx(expected, abs=1e-9)


def _grid_run(tmp_path: Path, truth: np.ndarray) -> Path:
    run = tmp_path / "calibration"
    run.mkdir()
    write_csv(run / "truth.csv", HEADER, ([k, *p] for k, p in enumerate(truth)))
    (run / "frames.npz").write_bytes(b"")
    return run


def test_samples_past_the_taxels_outline_do_not_tip_the_choice(tmp_path):
    """Six samples inside the taxels' outline, placed best with 4 frames; one past it,
    placed 20 mm off with 4 frames only: over all samples 8 frames would win, over the
    samples inside 4 do; with too few samples inside, all count."""
    taxels = np.array([[0, 0, 0], [30, 0, 0], [0, 30, 0], [30, 30, 0]], float)
    inside = np.array([[5, 5, 0], [15, 5, 0], [25, 5, 0], [5, 25, 0], [15, 25, 0], [25, 25, 0]])
    truth = np.vstack([inside, [[40.0, 15.0, 0.0]]]).astype(float)
    spread = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [1, 0, 0], [-1, 0, 0]])
    errors = {1: 2.0, 2: 1.5, 4: 0.5, 8: 0.75, 16: 1.0}

    def locate(frames: int, bench: Path, folder: Path) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        placed = truth.copy()
        placed[:6] += errors[frames] * spread
        placed[6, 1] += 20.0 if frames == 4 else 0.0
        write_csv(folder / "measured.csv", HEADER, ([k, *p] for k, p in enumerate(placed)))

    run = _grid_run(tmp_path, truth)
    assert model_frames.choose(locate, run, tmp_path / "all")[0] == 8
    chosen, tried = model_frames.choose(locate, run, tmp_path / "in", outline_mm=taxels)
    assert chosen == 4
    assert tried == pytest.approx(errors, abs=1e-9)  # the six inside, registered alone
    corner = taxels[[0, 1, 2]] * [0.5, 0.5, 1.0]  # an outline around one sample only
    assert model_frames.choose(locate, run, tmp_path / "few", outline_mm=corner)[0] == 8
