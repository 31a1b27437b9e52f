"""The model method's settings (`model_fit.tuned`: window and iteration cap), as `fruit
study locate` varies them: each still gives a footprint's point back, the cap is the fit's,
and the module's defaults come back after the block."""

import numpy as np
import pytest

from fruitcli.sensing.detection import model_fit
from fruitcli.sensing.detection.frames_to_touches import Locator, Stream
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.frames.board import default_board
from fruitcli.studies import locate_methods as lm
from tests.sensing.detection.test_model_fit import LAW, SIGMA_MM, grid_taxels


def fit_once(point, half=None, iterations=None):
    """The model's point for a noise-free footprint of width SIGMA_MM at `point`."""
    taxels = grid_taxels()
    d = np.linalg.norm(taxels.xyz_mm - point, axis=1)
    v = 60.0 * np.exp(-0.5 * (d / SIGMA_MM) ** 2)
    with model_fit.tuned(
        model_fit.HALF if half is None else half,
        model_fit.ITERATIONS if iterations is None else iterations,
    ):
        loc = Locator(taxels, default_board(), taxels.xyz_mm, Settings(method="model"), heights=LAW)
        assert loc.model[0].di.size == (2 * (half or model_fit.HALF) + 1) ** 2
        t = Stream(loc, np.zeros(len(taxels))).step(v)
    return t


@pytest.mark.parametrize("half", [1, 2])
def test_both_windows_give_a_noise_free_point_back(half):
    point = np.array([37.3, 27.1, 0.0])
    t = fit_once(point, half)
    assert t.fit[0] == model_fit.FIT_MODEL
    assert t.xyz_mm[0] == pytest.approx(point, abs=0.02)  # the profile's sampling


def test_the_iteration_cap_is_the_fits():
    point = np.array([37.3, 27.1, 0.0])
    one = np.linalg.norm(fit_once(point, iterations=1).xyz_mm[0] - point)
    many = np.linalg.norm(fit_once(point, iterations=30).xyz_mm[0] - point)
    assert many < 0.02 < one  # one step from N9's point is not there yet


def test_tuned_restores_the_defaults_and_refuses_nonsense():
    before = model_fit.HALF, model_fit.ITERATIONS
    with pytest.raises(RuntimeError), model_fit.tuned(1, 3):
        assert (model_fit.HALF, model_fit.ITERATIONS) == (1, 3)
        raise RuntimeError
    assert (model_fit.HALF, model_fit.ITERATIONS) == before
    with (
        pytest.raises(ValueError, match="expected half >= 1 and iterations >= 1, got 0, 3"),
        model_fit.tuned(0, 3),
    ):
        pass


def test_the_study_rows_are_every_method_then_the_model_settings():
    from fruitcli.sensing.detection.methods import METHODS

    rows = lm.variants()
    assert [r[0] for r in rows] == [*METHODS, *lm.MODEL_SETTINGS]
    assert {r[1]["detection.method"] for r in rows[len(METHODS) :]} == {"model"}
    assert [r[1]["detection.model_frames"] for r in rows[len(METHODS) :]] == [
        f for _, _, f in lm.MODEL_SETTINGS.values()
    ]
    label, _, setting = rows[len(METHODS)]
    half, cap, _ = lm.MODEL_SETTINGS[label]
    with setting():
        assert model_fit.HALF == half
        assert model_fit.ITERATIONS == (cap or 12)
    assert model_fit.ITERATIONS == 12


def test_tuned_blocks_in_two_threads_do_not_mix():
    """A second thread's block waits for the first's end: the first sees its own settings
    throughout (without the lock the second would overwrite them while it sleeps)."""
    import threading
    import time

    seen = {}
    entered = threading.Event()

    def first():
        with model_fit.tuned(1, 3):
            entered.set()
            start = (model_fit.HALF, model_fit.ITERATIONS)
            time.sleep(0.2)  # the second thread tries to enter meanwhile
            seen["first"] = (start, (model_fit.HALF, model_fit.ITERATIONS))

    def second():
        entered.wait()
        with model_fit.tuned(2, 7):
            seen["second"] = (model_fit.HALF, model_fit.ITERATIONS)
            time.sleep(0.4)  # still inside when the first looks again (without the lock)

    threads = [threading.Thread(target=first), threading.Thread(target=second)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert seen == {"first": ((1, 3), (1, 3)), "second": (2, 7)}
    assert (model_fit.HALF, model_fit.ITERATIONS) == (2, 12)
