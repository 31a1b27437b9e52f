"""The paper's observations next to a run's, read from the run's output files: the demo
report's section and the numbers behind it."""

from __future__ import annotations

import json
import math

import pytest

from fruitcli.workflow import observations as obs
from fruitcli.workflow.report import write_report


def _json(path, data) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data))


def _sensitivity(root, played, model, std, top) -> None:
    """A sensitivity.json whose largest played shift is taxel id `top`."""
    taxels = [
        {"id": 1, "i": 0, "j": 0, "std": 0.5, "max_shift": 1.0, "max_shift_model": 0.5, "fab": 1.0},
        {"id": 7, "i": 3, "j": 4, "std": 1.5, "max_shift": 9.0, "max_shift_model": 6.0, "fab": 2.0},
    ]
    assert taxels[1]["id"] == top
    _json(
        root / "sensitivity" / "sensitivity.json",
        {
            "summary": {
                "std": {"max": std[0], "mean": std[1]},
                "max_shift": {"max": played[0], "mean": played[1]},
                "max_shift_model": {"max": model[0], "mean": model[1]},
            },
            "taxels": taxels,
        },
    )


def _demo_outputs(tmp_path, skin: str = "") -> None:
    """The files the demo's scenes write, as small as the section reads them."""
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "fruit-rest.toml").write_text(
        '[bench]\nindenters = ["small", "medium"]\n[skin]\ncontact_counts = 60.0\n'
        "gap_decay_mm = 2.0\n" + skin
    )
    row = {"n": 37, "compare": {"translation": {"mean_mm": 2.494, "std_mm": 1.576}}}
    _json(
        tmp_path / "fruit-rest" / "evaluate" / "summary.json",
        {"rest-small": {"label": "Rest, small", **row}},
    )
    (tmp_path / "fruit-breathing" / "make-tracks").mkdir(parents=True)
    (tmp_path / "fruit-breathing" / "make-tracks" / "taxels.csv").write_text(
        "id,i,j,x_mm,y_mm,z_mm\n1,0,0,0,0,0\n7,3,4,10.2,-20.4,5.0\n"
    )
    _sensitivity(tmp_path / "fruit-breathing", (12.9, 5.2), (11.5, 2.9), (1.91, 1.21), 7)
    _sensitivity(tmp_path / "touchpad-4x4", (11.2, 4.0), (10.0, 3.0), (1.8, 1.2), 7)


NAMES = ["fruit-rest", "fruit-breathing", "touchpad-4x4"]


def test_gaussian_pretouch_is_the_closed_form():
    """60 exp(-g / 2) = 20 at g = 2 ln 3; a contact below the threshold never crosses."""
    assert obs.gaussian_pretouch_mm(60.0, 2.0) == pytest.approx(2.0 * math.log(3.0))
    assert obs.gaussian_pretouch_mm(15.0, 2.0) == 0.0


def test_rows_from_a_gaussian_run(tmp_path):
    _demo_outputs(tmp_path)
    rows = {a.split(":")[0]: c for a, _, c in obs.run_rows(tmp_path, NAMES)}
    assert rows["pre-touch"] == "small 2.20, medium 2.20 mm"
    assert rows["4 x 4 pad bent 180 deg (the jig bends it along x)"].startswith(
        "11.2 counts with noise, 10.0 the model alone's largest rise"
    )
    assert rows["the Fruit breathing"] == (
        "max 12.9, mean 5.2 counts with noise (the model alone, its largest rise: max 11.5, mean "
        "2.9); the "
        "largest at taxel (3, 4) at (10, -20, 5) mm, fabrication factor 2.00"
    )
    assert rows["noise"].startswith("max 1.91, mean 1.21 counts")
    assert rows["Table I, Rest, small"] == "2.49 ± 1.58 mm (n = 37)"
    assert rows["Table I, Rest, medium"] == "not run"
    assert rows["Table I, Deformed, small"] == "not run"


def test_rows_from_an_electrostatic_run_read_its_crossing(tmp_path):
    """With a crossing table in the run, its threshold gaps, not the scene's Gaussian."""
    _demo_outputs(tmp_path, 'model = "electrostatic"\n')
    _json(
        tmp_path / "fruit-rest" / "skin" / "summary.json",
        {
            "objects": {
                "small": {"threshold_gap_mm": 0.3, "contact_counts": 22.9},
                "medium": {"threshold_gap_mm": 3.69, "contact_counts": 88.1},
            }
        },
    )
    rows = obs.run_rows(tmp_path, NAMES)
    assert rows[0][0].endswith("(counts at contact: small 22.9, medium 88.1 counts)")
    assert rows[0][2] == "small 0.30, medium 3.69 mm"


def test_a_scene_not_run_says_so(tmp_path):
    rows = {a.split(":")[0]: c for a, _, c in obs.run_rows(tmp_path, ["paper-table"])}
    assert rows["pre-touch"] == "not run (fruit-rest)"
    assert rows["the Fruit breathing"] == "not run (fruit-breathing)"
    assert rows["Table I, Rest, small"] == "not run"


def test_the_report_holds_the_section(tmp_path):
    """In report.md; a bench registered by translation itself (no `compare`) is read too."""
    _demo_outputs(tmp_path)
    row = {"label": "Rest, small", "n": 37, "register": "translation"}
    _json(
        tmp_path / "fruit-rest" / "evaluate" / "summary.json",
        {"rest-small": {**row, "mean_mm": 2.494, "std_mm": 1.576}},
    )
    plans = {n: "" for n in NAMES}
    report = write_report(tmp_path, plans, {n: (1.0, 1, 0) for n in NAMES}).read_text()
    assert "## The paper's observations against this run" in report
    assert "Skin model: gaussian" in report
    assert (
        "| Table I, Rest, small: translation-registered error | 2.6 ± 1.3 mm | "
        "2.49 ± 1.58 mm (n = 37) |" in report
    )
