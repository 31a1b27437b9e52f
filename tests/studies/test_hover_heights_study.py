"""fruit study heights: calibrations recover the skin they were recorded on, and heights
on descents they were not recorded on come back within a fraction of the gap decay."""

import numpy as np
import pytest

from fruitcli.sensing.skin import forward
from fruitcli.studies import hover_heights as hh


@pytest.mark.parametrize("spread", [0.0, 0.2])
def test_calibration_recovers_the_skin_it_was_recorded_on(spread):
    params, fit, taxels = hh.calibrated(0, spread)
    assert len(taxels) == 252
    assert fit["gap_decay_mm"] == pytest.approx(forward.GAP_DECAY_MM, rel=0.03)
    assert fit["sigma_mm"] == pytest.approx(forward.default_footprints_mm()["small"], rel=0.03)
    assert fit["contact_counts"] == pytest.approx(forward.CONTACT_COUNTS, rel=0.05)
    assert params.gain_spread == 0.0  # fitted as a uniform skin


def test_every_run_and_band_with_hovers_and_touches(tmp_path):
    res = hh.write(tmp_path / "h")
    rows, extras = res["rows"], res["extras"]
    assert [r[0] for r in rows[:: len(hh.BANDS)]] == [r[0] for r in hh.RUNS]
    assert len(rows) == len(hh.RUNS) * len(hh.BANDS)
    for name, *_ in hh.RUNS:
        near = next(r for r in rows if r[0] == name and r[1] == "0-0.5")
        assert near[2] > 500 and near[3] < 0.3  # mm: well inside the 2 mm gap decay
        e = extras[name]
        assert 1.5 < e["largest_hover_mm"] < 4.0
        assert np.isfinite([e["hover_position_error_mm"], e["touch_position_error_mm"]]).all()
    text = (tmp_path / "h" / "hover_heights.md").read_text()
    assert "calibrated on a gain spread 0.2" in text
    assert (tmp_path / "h" / "hover_heights.csv").exists()
