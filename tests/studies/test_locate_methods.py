"""`fruit study locate`'s pieces: the bench skins differ from the locator's, the methods'
table feeds the schema and the command line, the model's share and 1-sigma radius are read
from touches.csv, the taxels' outline is seen from above."""

import numpy as np
import pytest
from click.testing import CliRunner
from matplotlib import pyplot as plt

from fruitcli.cli.main import cli
from fruitcli.scene import SCHEMA
from fruitcli.sensing.detection.methods import METHODS
from fruitcli.sensing.skin import forward
from fruitcli.studies import locate_methods as lm


def test_every_bench_skin_differs_from_the_scene_default():
    for name in lm.BENCH_SKINS:
        values = lm.bench_skin_values(name, ["small", "medium"])
        assert values["skin.gain_spread"] == pytest.approx(0.2)
        feet = values.get("skin.footprint_sigma_mm")
        if feet is not None:
            assert feet != forward.default_footprints_mm()
            assert feet["small"] == pytest.approx(
                np.hypot(lm.BENCH_SKINS[name]["field_sigma_mm"], 1.5)
            )


def test_the_methods_table_is_what_the_schema_and_the_cli_offer():
    assert SCHEMA["detection"]["method"].choices == tuple(METHODS)
    out = CliRunner().invoke(cli, ["locate", "--help"], terminal_width=200).output
    assert "[n9|n9_floor|peaks|fit2|model]" in out.replace("\n", "").replace(" ", "")


def test_model_fits_reads_the_fit_and_radius_columns(tmp_path):
    p = tmp_path / "touches.csv"
    p.write_text("# c\nframe,pos_err_mm,fit\n1,1.5,model\n2,nan,n9\n3,0.5,model\n4,2.5,model\n")
    share, sigma = lm.model_fits(p)
    assert share == pytest.approx(0.75)
    assert sigma == pytest.approx(1.5)  # the median over the model's three
    p.write_text("# c\nframe,kind\n1,touch\n")
    assert all(np.isnan(lm.model_fits(p)))


def test_the_table_names_its_skins_and_stamp():
    row = {
        "bench_skin": "wider",
        "method": "model",
        "indenter": "small",
        "n": 3,
        "mean_mm": 1.0,
        "reg_mean_mm": 0.5,
        "reg_std_mm": 0.2,
        "reg_median_mm": 0.4,
        "us_per_frame": 12.0,
        "model_share": 1.0,
        "model_sigma_mm": 0.8,
        "n_inside": 2,
        "reg_mean_inside_mm": 0.3,
    }
    text = lm.table_markdown([row], "pad", "Run now.")
    assert (
        "| wider | model | small | 3 | 1.00 mm | 0.50 mm | 0.20 mm | 0.40 mm | 2, 0.30 mm "
        "| 12.0 | 100 % | 0.80 mm |" in text
    )
    assert "Run now." in text and "field sigma 7 mm" in text


def test_the_plot_has_a_panel_per_board(tmp_path):
    rows = [
        {"bench_skin": skin, "method": m, "indenter": ind, "reg_mean_mm": e, "us_per_frame": t}
        for skin in ("calibrated", "wider")
        for m, e, t in (("n9", 2.5, 3.0), ("model", 1.5, 900.0))
        for ind in ("small", "medium")
    ]
    path = tmp_path / "methods.png"
    lm.plot(path, rows, "pad")
    image = plt.imread(path)
    assert image.shape[1] > 2 * image.shape[0]  # two panels side by side, the legend beside
