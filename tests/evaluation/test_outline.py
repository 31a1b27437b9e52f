"""Where the taxels place a touch (`fruitcli.evaluation.outline`)."""

import numpy as np
import pytest

from fruitcli.evaluation.outline import inside_outline, registered_mean


def test_inside_outline_is_the_taxels_hull_seen_from_above():
    taxels = np.array([[0, 0, 0], [16, 0, 1], [0, 16, 2], [16, 16, 3]], float)
    points = np.array([[8, 8, -20], [15.9, 0.1, 5], [20, 8, 0], [-0.1, 8, 0]], float)
    assert inside_outline(points, taxels).tolist() == [True, True, False, False]
    assert inside_outline(np.zeros((0, 3)), taxels).size == 0


def test_the_registered_mean_removes_a_common_shift():
    truth = np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0], [10, 10, 0]], float)
    spread = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]], float)
    assert registered_mean(truth, truth + [3.0, -2.0, 0.5] + spread) == pytest.approx(1.0)
    assert np.isnan(registered_mean(np.zeros((0, 3)), np.zeros((0, 3))))
