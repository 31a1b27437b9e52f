"""The footprint's widening with the gap ([skin].widening_per_mm): the virtual bench's law,
`fruit calibrate`'s fit of it, the model method's use of it; and the reference of the
one-pitch test for a touch that took its second explanation."""

import numpy as np
import pytest

from fruitcli.sensing.detection.model_fit import FIT_MODEL, FIT_N9
from fruitcli.sensing.skin import forward
from fruitcli.sensing.skin.calibrate import fit_skin
from fruitcli.sensing.skin.heights import GapLaw
from tests.sensing.detection.test_model_fit import locate
from tests.sensing.detection.test_model_height_form import (
    AS_GAP,
    DECAY_MM,
    SIGMA_MM,
    FirstFitHeld,
    board_frames,
    calibration_descents,
    dome_taxels,
    gap_form_counts,
    on_dome,
)

WIDENING = 0.06  # the hidden skin's growth of its width per mm of gap


def widening_counts(taxels_mm, point, amplitude=60.0, gap=0.0):
    """A gap-form skin whose width grows with the gap: amplitude exp(-r^2 / 2 S^2)
    exp(-(gap + AS_GAP |h|) / DECAY_MM), S = SIGMA_MM (1 + WIDENING (gap + AS_GAP |h|))."""
    off = point - taxels_mm
    r2 = off[:, 0] ** 2 + off[:, 1] ** 2
    g = gap + AS_GAP * np.abs(off[:, 2])
    width = SIGMA_MM * (1.0 + WIDENING * g)
    return amplitude * np.exp(-0.5 * r2 / width**2 - g / DECAY_MM)


def test_the_bench_law_widens_with_the_gap_and_the_heights_share():
    params = forward.SkinParams(
        forward.default_footprints_mm(),
        height_as_distance=0.0,
        height_as_gap=0.5,
        widening_per_mm=0.1,
    )
    skin = forward.Skin(np.zeros(2), np.ones(2), np.ones(2), None, params)
    dist, height = np.array([[5.0, 5.0]] * 2), np.array([[4.0, -4.0]] * 2)
    gaps = np.array([1.0, -0.5])  # above the surface, and pressing in (no widening)
    got = forward.activation_counts(dist, gaps, "small", skin, height)
    sigma = forward.footprint_sigma_mm("small")
    r2 = 5.0**2 - 4.0**2
    for row, gap in enumerate(gaps):
        width = sigma * (1.0 + 0.1 * (max(gap, 0.0) + 0.5 * 4.0))
        want = 60.0 * np.exp(-0.5 * r2 / width**2 - (gap + 0.5 * 4.0) / 2.0)
        assert got[row] == pytest.approx([want, want], rel=1e-12)


def test_calibration_finds_the_widening():
    v, dist, gap, height, _ = calibration_descents(0.0, AS_GAP, widening=WIDENING)
    fit = fit_skin(v, dist, gap, height)
    assert fit["widening_gain"] > 0.01 * v.size  # kept: well over the criterion
    assert fit["widening_per_mm"] == pytest.approx(WIDENING, abs=0.01)
    assert fit["sigma_mm"] == pytest.approx(SIGMA_MM, rel=0.05)
    assert fit["height_as_gap"] == pytest.approx(AS_GAP, abs=0.1)
    assert fit["gap_decay_mm"] == pytest.approx(DECAY_MM, rel=0.05)


def test_a_footprint_that_does_not_widen_is_calibrated_without_it():
    """The same skin without the widening: it does not pay for itself and stays 0, the
    law the same as fitted without trying it."""
    from fruitcli.sensing.skin import calibrate

    v, dist, gap, height, _ = calibration_descents(0.0, AS_GAP)
    fit = fit_skin(v, dist, gap, height)
    assert fit["widening_per_mm"] == 0.0
    assert fit["widening_gain"] < 2.0 * np.log(v.size)
    form = calibrate._fit_law(v, dist, gap, height)
    for key in ("contact_counts", "sigma_mm", "gap_decay_mm", "height_as_gap", "rms_counts"):
        assert fit[key] == form[key]


@pytest.mark.parametrize("point_xy", [(7.0, 4.0), (26.0, -9.0)])
def test_a_touch_on_a_widening_skin_comes_back_with_its_widening(point_xy):
    """Frames of a skin whose width grows with the gap, a touch on the dome 1.5 and 7 mm
    below its top: located with the skin's law the point comes back within its
    uncertainty, and nearer than with the same law without the widening."""
    taxels = dome_taxels()
    point = np.array([*point_xy, on_dome(*point_xy)])
    frames = board_frames(taxels, widening_counts(taxels.xyz_mm, point), noise=0.5)
    law = GapLaw(60.0, DECAY_MM, SIGMA_MM, 1.0, None, 0.0, AS_GAP, WIDENING)
    t = locate(taxels, frames, heights=law)
    assert (t.fit == FIT_MODEL).all()
    err = np.linalg.norm(t.xyz_mm - point, axis=1)
    assert (err <= 3.0 * t.pos_err_mm + 0.05).all()
    narrow_law = GapLaw(60.0, DECAY_MM, SIGMA_MM, 1.0, None, 0.0, AS_GAP)
    narrow = locate(taxels, frames, heights=narrow_law)
    assert err.mean() < np.linalg.norm(narrow.xyz_mm - point, axis=1).mean()


def test_a_touch_that_took_its_second_fit_is_held_to_its_peak_taxel(monkeypatch):
    """The one-pitch test measures a touch's point from N9's, or, once the touch took its
    second explanation's point, from its peak taxel: N9's point lies on the other side.
    A touch 3 mm inside the dome's last column (x = 36 mm), its first fit held 1.2
    pitches out from N9's point (under one pitch from the peak): kept as the first fit,
    it fails the test; the same point taken as a second fit passes it."""
    from fruitcli.sensing.detection import model_fit, model_kernel

    taxels = dome_taxels()
    point = np.array([33.0, 3.0, on_dome(33.0, 3.0)])
    frames = board_frames(taxels, gap_form_counts(taxels.xyz_mm, point), n=3)
    law = GapLaw(60.0, DECAY_MM, SIGMA_MM, 1.0, None, 0.0, AS_GAP)
    starts = []

    def record(x0, *rest):
        starts.append(x0[:, 0].copy())
        fit_all(x0, *rest)

    fit_all = model_kernel.fit_all
    monkeypatch.setattr(model_kernel, "fit_all", record)
    locate(taxels, frames, heights=law)
    n9_a = starts[0]  # grid units from the peak taxel
    assert (n9_a < -0.2).all() and (np.abs(n9_a + 1.2) < 1.0).all()
    monkeypatch.setattr(model_kernel, "fit_all", FirstFitHeld(fit_all, shift=1.2))
    monkeypatch.setattr(model_fit, "MIRROR_KEEP", np.inf)  # no second fit is taken
    assert (locate(taxels, frames, heights=law).fit == FIT_N9).all()

    mirror = model_fit._mirror_spread

    def swap(out, *args):  # the first fit's point moved as a swap would move it
        spread, _ = mirror(out, *args)
        out[:, 0] += 1.2
        return spread, np.ones(len(out), bool)

    monkeypatch.setattr(model_kernel, "fit_all", FirstFitHeld(fit_all))
    monkeypatch.setattr(model_fit, "_mirror_spread", swap)
    assert (locate(taxels, frames, heights=law).fit == FIT_MODEL).all()
