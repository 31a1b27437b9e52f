"""The demo's model rows of Table I (stage ``model-rows``): the bench's own frames located
by the model with a skin `fruit calibrate` fitted to another run, and the report's rows."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fruitcli.fsutil import write_csv
from fruitcli.scene import load_scene
from fruitcli.workflow import planner
from fruitcli.workflow.model_rows import MODEL_ROWS
from fruitcli.workflow.report import table_section
from fruitcli.workflow.stages import STAGES
from tests.sensing.skin.test_calibrate import HIDDEN_SKIN, virtual_bench_scene


def test_model_rows_locate_the_bench_frames_with_a_calibrated_skin(tmp_path):
    """Run under the read recorder of `test_stage_hashes`: every scene key the stage
    reads is declared, and every stage folder it opens is one of its deps."""
    from tests.workflow.read_recorder import recording
    from tests.workflow.test_stage_hashes import _covered

    (tmp_path / "scene").mkdir()
    path = virtual_bench_scene(tmp_path / "scene", HIDDEN_SKIN.replace("4.5", "6.5"))
    c = np.linspace(-15.0, 15.0, 4)  # over the pad's inner taxels: every sample found
    write_csv(
        tmp_path / "scene" / "samples.csv",
        ["sample", "x_mm", "y_mm"],
        ([n, float(x), float(y)] for n, (x, y) in enumerate((x, y) for x in c for y in c)),
    )
    scene = load_scene(path)
    out = tmp_path / "out"
    mp = pytest.MonkeyPatch()
    try:
        with recording(mp) as reads:
            reads.watch(scene)
            steps = planner.run(scene, out / "pad", stages=reads.wrap([*STAGES, MODEL_ROWS]))
    finally:
        mp.undo()
    assert [s.action for s in steps if s.stage in ("evaluate", "model-rows")] == ["run", "run"]
    seen = reads.seen["model-rows"]
    assert "skin.footprint_sigma_mm" in seen["run"]  # the recorder sees the stage's reads
    undeclared = [
        (phase, e) for phase, es in seen.items() for e in es if not _covered(e, MODEL_ROWS, phase)
    ]
    assert undeclared == [], str(sorted(undeclared))
    assert reads.dirs["model-rows"] <= set(MODEL_ROWS.deps)
    data = json.loads((out / "pad" / "model-rows" / "summary.json").read_text())
    cal = data["calibration"]
    # fitted to the second run of the hidden skin (6.5 mm, 80 counts), not handed it
    assert cal["footprint_sigma_mm"]["small"] == pytest.approx(6.5, rel=0.15)
    assert cal["footprint_sigma_mm"]["small"] != 6.5
    assert cal["contact_counts"] == pytest.approx(80.0, rel=0.25)  # gains +-20 % share it
    assert (cal["board"], cal["indenter"]) == ("gaussian", "small")
    n9 = json.loads((out / "pad" / "evaluate" / "summary.json").read_text())
    (n9_row,) = n9.values()
    (label, row) = data["rows"].popitem()
    assert label == n9_row["label"] and row["n"] == n9_row["n"]  # the same samples
    assert 0.5 < row["model_share"] <= 1.0
    header = (out / "pad" / "model-rows" / "locate" / "small" / "touches.csv").read_text()
    assert ",fit\n" in header  # located by the model method
    # the calibration's own bench run is at other sample points than the scored one
    cal_truth = out / "pad" / "model-rows" / "calibration" / "bench" / "small" / "truth.csv"
    scored = (out / "pad" / "bench" / "small" / "truth.csv").read_text()
    assert cal_truth.read_text() != scored
    # a second run reuses it
    steps = planner.run(scene, out / "pad", stages=[*STAGES, MODEL_ROWS])
    assert {s.stage: s.action for s in steps}["model-rows"] == "reuse"


def _summary(mean, label="Rest, small"):
    stats = {
        "mean_mm": mean,
        "std_mm": 1.0,
        "bias_mm": [0.5, -0.25, 0.0],
        "rmse_mm": 2.0,
        "median_mm": 1.5,
        "p95_mm": 4.0,
        "max_mm": 5.0,
        "ci95_mean_mm": [1.0, 3.0],
    }
    return {
        "label": label,
        "n": 10,
        "reference_length_mm": 152.0,
        "compare": {"none": stats, "translation": {**stats, "mean_mm": mean - 0.5}},
    }


def test_the_report_puts_the_model_rows_under_their_scene_and_says_how(tmp_path):
    ev = tmp_path / "fruit-rest" / "evaluate"
    ev.mkdir(parents=True)
    (ev / "summary.json").write_text(json.dumps({"rest-small": _summary(3.04)}))
    lines = table_section(tmp_path, ["fruit-rest"])
    assert not any(", model" in line for line in lines)  # no stage output: N9's rows only
    mr = tmp_path / "fruit-rest" / "model-rows"
    mr.mkdir()
    row = {k: v for k, v in _summary(1.52).items() if k != "label"}
    cal = {
        "board": "gaussian",
        "indenter": "small",
        "samples": "half a pitch off each taxel and right over each taxel",
        "footprint_sigma_mm": {"small": 6.38},
        "contact_counts": 55.3,
        "gap_decay_mm": 2.02,
    }
    data = {"calibration": cal, "rows": {"Rest, small": {"model_share": 0.9, **row}}}
    (mr / "summary.json").write_text(json.dumps(data))
    lines = table_section(tmp_path, ["fruit-rest"])
    n9 = lines.index(
        "| Rest, small (ours: fruit-rest) | 10 | 3.04 (2.0 %) / 1.00 (0.7 %) | "
        "2.54 (1.7 %) / 1.00 (0.7 %) | 2.6 (1.7 %) / 1.3 (0.8 %) | (+0.50, -0.25, +0.00) |"
    )
    assert lines[n9 + 1] == (
        "| Rest, small (ours: fruit-rest, model, the frame at the threshold, 90 % placed by "
        "the fit) | 10 | 1.52 (1.0 %) / 1.00 (0.7 %) | 1.02 (0.7 %) / 1.00 (0.7 %) | - | "
        "(+0.50, -0.25, +0.00) |"
    )
    assert (
        "- fruit-rest (board's skin: gaussian; fitted: the Gaussian law): footprint sigma (mm) "
        "small 6.38, 55.3 counts at contact, gap decay 2.02 mm"
    ) in lines
    # with a mean of frames chosen on the calibration run: both settings' rows, and the
    # calibration's errors in the line that says how
    four = {k: v for k, v in _summary(1.20).items() if k != "label"}
    data |= {
        "model_frames": {"chosen": 4, "calibration_error_mm": {"1": 1.5, "4": 1.3}},
        "rows_by_frames": {
            "1": data["rows"],
            "4": {"Rest, small": {"model_share": 0.9, **four}},
        },
    }
    (mr / "summary.json").write_text(json.dumps(data))
    lines = table_section(tmp_path, ["fruit-rest"])
    assert lines[n9 + 2].startswith(
        "| Rest, small (ours: fruit-rest, model, mean of 4 frames, chosen on the calibration "
        "run, 90 % placed by the fit) | 10 | 1.20 (0.8 %)"
    )
    assert any(
        "the calibration run's touches placed by the mean of 1 frame(s) 1.50 mm, 4 frame(s) "
        "1.30 mm" in line
        for line in lines
    )
    # the calibration's height form: said as 3D distance, or with its two terms
    for form, said in (
        ((1.0, 0.0), "gap decay 2.02 mm, a crossing's height difference as 3D distance;"),
        ((0.0, 0.72), "a crossing's height difference as distance 0.00 and as gap 0.72;"),
    ):
        cal |= {"height_as_distance": form[0], "height_as_gap": form[1]}
        (mr / "summary.json").write_text(json.dumps(data))
        assert any(said in line for line in table_section(tmp_path, ["fruit-rest"]))
    # and its widening with the gap, once calibrated
    cal |= {"widening_per_mm": 0.071}
    (mr / "summary.json").write_text(json.dumps(data))
    said = "as gap 0.72, the footprint 7.1 % wider per mm of gap;"
    assert any(said in line for line in table_section(tmp_path, ["fruit-rest"]))
    # a summary of another form (an older run's) leaves the rows out, no error
    (mr / "summary.json").write_text(json.dumps({"rows": {}}))
    assert not any(", model" in line for line in table_section(tmp_path, ["fruit-rest"]))
