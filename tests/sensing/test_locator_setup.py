"""`build_locator` hands each of its inputs to the `Locator` parameter that names it."""

from types import SimpleNamespace

import numpy as np

from fruitcli.sensing.detection.locate import States
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.frames.board import default_board
from fruitcli.sensing.locator_setup import build_locator
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
