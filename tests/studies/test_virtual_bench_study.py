"""`fruit study bench`: the bench's Table I rows against the skin model's parameters."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fruitcli.evaluation.report import evaluate_pair
from fruitcli.scene import load_scene
from fruitcli.sensing.stages import run_bench
from fruitcli.studies import virtual_bench_study as bs
from tests.helpers.locate import locate_scene
from tests.sensing.skin.test_virtual_bench import pad_taxel_csv


def pad_scene(tmp_path):
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    path = tmp_path / "pad.toml"
    path.write_text(
        f'[scene]\nname = "pad"\n[grid]\ntaxels = "{taxels}"\nspacing_x_mm = 16.0\n'
        'spacing_y_mm = 16.0\n[bench]\nindenters = ["small", "medium"]\nseed = 3\n'
    )
    return path, taxels


def test_cases_move_one_parameter_at_a_time(tmp_path):
    path, _ = pad_scene(tmp_path)
    skin = load_scene(path).skin
    cases = bs.cases(skin, ["small", "medium"])
    assert cases[0].parameter == "default" and cases[0].skin == {}
    assert all(len(c.skin) == 1 for c in cases[1:])
    feet = [c for c in cases if c.parameter == "footprint"]
    assert [c.value for c in feet] == [4.0, 5.0, 7.0, 8.0]  # 6 mm is the default
    assert feet[0].skin["footprint_sigma_mm"]["small"] == pytest.approx(np.hypot(4, 1.5))
    assert not any(c.parameter == "gain_spread" and c.value == 0 for c in cases)
    assert not any(c.parameter == "project" for c in cases)  # no body surface given
    last = bs.cases(skin, ["small"], surface=True)[-1]
    assert last.detection == {"project": "surface"} and last.skin == {}


def test_study_bench_table_plot_and_the_default_row(fruit, tmp_path):
    path, taxels = pad_scene(tmp_path)
    out = tmp_path / "study"
    res = fruit("study", "bench", path, "--out", out, "--jobs", "1")
    assert res.exit_code == 0, res.output
    data = json.loads((out / "bench.json").read_text())
    n_cases = len(bs.cases(load_scene(path).skin, ["small", "medium"]))
    assert len(data["rows"]) == 2 * n_cases
    assert (out / "bench.png").read_bytes()[:4] == b"\x89PNG"
    assert "| default | small |" in (out / "bench.md").read_text()
    assert (out / "bench.csv").read_text().count("\n") > 2 * n_cases
    # the default row is the scene's own bench, located and evaluated
    sc = load_scene(path)
    run_bench(sc, taxels, None, tmp_path / "b")
    locate_scene(sc, tmp_path / "b" / "small" / "frames.npz", taxels, None, tmp_path / "l")
    s, *_ = evaluate_pair(tmp_path / "b" / "small" / "truth.csv", tmp_path / "l" / "measured.csv")
    default = next(
        r for r in data["rows"] if r["setting"] == "default" and r["indenter"] == "small"
    )
    assert default["mean_mm"] == pytest.approx(s["compare"]["none"]["mean_mm"], abs=1e-12)
    assert default["reg_mean_mm"] == pytest.approx(
        s["compare"]["translation"]["mean_mm"], abs=1e-12
    )
    # the footprint moves the row
    feet = {
        r["value"]: r["mean_mm"]
        for r in data["rows"]
        if r["parameter"] == "footprint" and r["indenter"] == "small"
    }
    assert len(set(np.round(list(feet.values()), 6))) > 1


def test_study_bench_needs_a_bench(fruit, tmp_path):
    (tmp_path / "s.toml").write_text('[scene]\nname = "x"\n')
    res = fruit("study", "bench", tmp_path / "s.toml", "--out", tmp_path / "o")
    assert res.exit_code == 2 and "the scene has no [bench] to study" in res.output
