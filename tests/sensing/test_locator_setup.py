"""`build_locator` hands each of its inputs to the `Locator` parameter that names it;
`idle_settings` takes the baseline over every idle frame a recording begins with."""

from types import SimpleNamespace

import numpy as np
import pytest

from fruitcli.errors import FrameError
from fruitcli.sensing.detection.locate import States
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.frames.board import default_board
from fruitcli.sensing.locator_setup import build_locator, idle_settings
from fruitcli.tables import Taxels


def _taxels() -> Taxels:
    i, j = (a.ravel() for a in np.meshgrid(np.arange(3), np.arange(3), indexing="ij"))
    return Taxels(np.arange(9), i, j, np.column_stack([i * 16.0, j * 12.0, np.zeros(9)]))


def _states(taxels: Taxels, n: int) -> States:
    return States(
        rest_nodes=np.eye(4, 3),
        tets=np.array([[0, 1, 2, 3]]),
        surface_tris=np.array([[0, 1, 2]]),
        displacement_mm=np.zeros((n, 4, 3)),
        pressure_kpa=np.linspace(0.0, 10.0, n)[:, None],
        chamber_names=("a",),
        taxels_mm=np.repeat(taxels.xyz_mm[None], n, axis=0),
        taxel_tet=np.zeros(len(taxels), np.int64),
        taxel_bary=np.full((len(taxels), 4), 0.25),
    )


def test_the_state_path_locator_divides_by_the_gains_and_has_no_reduced_model():
    taxels, board = _taxels(), default_board()
    rec = SimpleNamespace(
        frame_shape=(board.rows, board.cols),
        pressure_kpa=np.array([[1.0], [2.0]]),
        chamber_names=("a",),
        meta={},
    )
    gain = np.linspace(0.8, 1.2, len(taxels))
    loc, pressure = build_locator(
        board, taxels, _states(taxels, 3), rec, Settings(), "test", gain=gain
    )
    assert loc.reduced is None
    np.testing.assert_array_equal(loc.gain, gain)
    np.testing.assert_array_equal(loc.state_pressure_kpa, [[0.0], [5.0], [10.0]])
    np.testing.assert_array_equal(pressure, [[1.0], [2.0]])


def test_the_baseline_takes_every_idle_frame_the_recording_begins_with():
    """A recording whose meta says it begins with more idle frames than
    ``[detection].baseline_frames`` (a bench's) has its baseline over all of them; fewer,
    or none said, keep the setting; a count that is not an integer 1 .. N - 1 is one line."""
    settings = Settings(baseline_frames=10)
    assert idle_settings(settings, {"baseline_frames": 120}, 500, "r").baseline_frames == 120
    assert idle_settings(settings, {"baseline_frames": 5}, 500, "r") is settings
    assert idle_settings(settings, {}, 500, "r") is settings
    for bad in (0, 500, 2.5, "120", True):
        with pytest.raises(FrameError) as info:
            idle_settings(settings, {"baseline_frames": bad}, 500, "r.npz")
        assert str(info.value) == (
            "r.npz: meta baseline_frames (the idle frames it begins with): expected an "
            f"integer 1 .. 499, got {bad!r}"
        )
