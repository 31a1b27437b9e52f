"""The footprint's height form ([skin].height_as_distance, height_as_gap): how a crossing's
height difference from the contact point enters the model method's fit, the virtual
bench and `fruit calibrate`."""

import numpy as np
import pytest

from fruitcli.sensing.detection.model_fit import FIT_MODEL, FootprintLaw
from fruitcli.sensing.detection.model_kernel import _residuals
from fruitcli.sensing.skin import forward
from fruitcli.sensing.skin.calibrate import fit_skin
from fruitcli.sensing.skin.heights import GapLaw
from fruitcli.tables import Taxels
from tests.sensing.detection.test_model_fit import BASE, locate

SIGMA_MM = 6.5
DECAY_MM = 6.0
AS_GAP = 0.8  # the hidden skin's share of the height difference taken as gap
DOME_MM = 60.0  # radius of the sphere the taxels lie on


def dome_taxels(rows=7, cols=7, pitch=12.0):
    """rows x cols taxels `pitch` apart in x, y, lifted onto a sphere of ``DOME_MM``
    whose top is at the grid's centre, z = 0 there."""
    i, j = (a.ravel() for a in np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"))
    x, y = pitch * (i - (rows - 1) / 2), pitch * (j - (cols - 1) / 2)
    return Taxels(np.arange(i.size), i, j, np.stack([x, y, on_dome(x, y)], axis=1))


def on_dome(x, y):
    return np.sqrt(DOME_MM**2 - x**2 - y**2) - DOME_MM


def gap_form_counts(taxels_mm, point, amplitude=60.0):
    """A skin that takes a crossing's height difference h as gap: amplitude
    exp(-r^2 / 2 sigma^2) exp(-AS_GAP |h| / DECAY_MM), r the offset across z."""
    off = point - taxels_mm
    r2 = off[:, 0] ** 2 + off[:, 1] ** 2
    return amplitude * np.exp(-0.5 * r2 / SIGMA_MM**2 - AS_GAP * np.abs(off[:, 2]) / DECAY_MM)


def board_frames(taxels, v, noise=1.0, n=20):
    from fruitcli.sensing.frames.board import default_board, taxel_cells

    rows, cols = taxel_cells(taxels, default_board(), "taxels")
    out = []
    for seed in range(n):
        f = np.full((21, 12), BASE)
        noisy = v + np.random.default_rng(seed).normal(0.0, noise, v.size)
        f[rows, cols] += np.maximum(noisy, 0.0)
        out.append(np.round(f).astype(np.int64))
    return out


@pytest.mark.parametrize("omega", [0.0, 0.06])
def test_the_residuals_jacobian_is_their_derivative(omega):
    """Analytic against central differences, with both height terms on, on a curved map,
    without and with the footprint's widening."""
    rng = np.random.default_rng(3)
    coef = np.zeros((6, 3))
    coef[1, 0], coef[2, 1] = 12.0, 12.0  # x = 12 a, y = 12 b
    coef[3, 2], coef[5, 2], coef[4, 2] = -1.6, -1.2, 0.3  # z curves down away from the centre
    corr = np.zeros((5, 5, 3))
    pos = np.column_stack([rng.uniform(-24, 24, 25), rng.uniform(-24, 24, 25), np.zeros(25)])
    pos[:, 2] = -0.011 * pos[:, 0] ** 2 - 0.008 * pos[:, 1] ** 2 + rng.uniform(-1, 1, 25)
    v = rng.uniform(0, 40, 25)
    inv_e, gain = rng.uniform(0.3, 1.0, 25), rng.uniform(0.8, 1.2, 25)
    d = np.arange(0.0, 80.0, 0.05)
    profile = np.exp(-0.5 * (d / SIGMA_MM) ** 2)
    height = np.array([0.3, 0.15, omega])
    jac, res, pt = np.empty((26, 4)), np.empty(26), np.empty((3, 3))

    def residuals(x):
        r = np.empty(26)
        _residuals(x, v, inv_e, gain, pos, coef, corr, 1, profile, 0.05, height, 0.15,
                   np.empty((26, 4)), r, pt)  # fmt: skip
        return r

    x = np.array([0.31, -0.27, 45.0, 1.07])
    _residuals(x, v, inv_e, gain, pos, coef, corr, 1, profile, 0.05, height, 0.15, jac, res, pt)
    for p in range(4):
        step = 1e-6 * max(abs(x[p]), 1.0)
        up, down = x.copy(), x.copy()
        up[p] += step
        down[p] -= step
        numeric = (residuals(up) - residuals(down)) / (2 * step)
        assert jac[:, p] == pytest.approx(numeric, rel=1e-4, abs=1e-6)


def test_the_default_form_is_the_3d_distance_bit_for_bit():
    """height_as_distance 1, height_as_gap 0: the law of `forward` before the two keys."""
    rng = np.random.default_rng(0)
    dist, height = rng.uniform(0, 20, (4, 9)), rng.uniform(-5, 5, (4, 9))
    gaps = np.linspace(3.0, -0.5, 4)
    plain = forward.activation_counts(dist, gaps, "small")
    assert np.array_equal(forward.activation_counts(dist, gaps, "small", None, height), plain)
    sigma = forward.footprint_sigma_mm("small")
    lateral = np.exp(-0.5 * (dist / sigma) ** 2)
    assert plain == pytest.approx(60.0 * lateral * np.exp(-gaps / 2.0)[:, None], rel=1e-12)


def test_the_bench_law_with_the_height_as_gap():
    params = forward.SkinParams(
        forward.default_footprints_mm(), height_as_distance=0.0, height_as_gap=1.0
    )
    skin = forward.Skin(np.zeros(2), np.ones(2), np.ones(2), None, params)
    dist, height = np.array([[5.0, 5.0]]), np.array([[3.0, -3.0]])  # above and below alike
    got = forward.activation_counts(dist, np.array([1.0]), "small", skin, height)
    sigma = forward.footprint_sigma_mm("small")
    want = 60.0 * np.exp(-0.5 * (5.0**2 - 3.0**2) / sigma**2) * np.exp(-(1.0 + 3.0) / 2.0)
    assert got == pytest.approx(np.full((1, 2), want), rel=1e-12)


@pytest.mark.parametrize("point_xy", [(7.0, 4.0), (22.0, -9.0)])
def test_a_touch_on_a_dome_of_a_gap_form_skin_comes_back_with_its_form(point_xy):
    """Frames of a skin that takes the height difference as gap, on a dome (the point 1.5
    and 4.3 mm below the top): located with the skin's form the point comes back within
    its uncertainty and better than with the 3D distance's form."""
    taxels = dome_taxels()
    point = np.array([*point_xy, on_dome(*point_xy)])
    frames = board_frames(taxels, gap_form_counts(taxels.xyz_mm, point))
    form = GapLaw(60.0, DECAY_MM, SIGMA_MM, 1.0, None, 0.0, AS_GAP)
    t = locate(taxels, frames, heights=form)
    assert (t.fit == FIT_MODEL).all()
    err = np.linalg.norm(t.xyz_mm - point, axis=1)
    assert (err <= 3.0 * t.pos_err_mm + 0.05).all()
    distance = locate(taxels, frames, heights=GapLaw(60.0, DECAY_MM, SIGMA_MM, 1.0))
    err_distance = np.linalg.norm(distance.xyz_mm - point, axis=1)
    assert err.mean() < err_distance.mean()


def test_the_footprint_law_carries_the_skins_form():
    law = FootprintLaw.of(GapLaw(60.0, 4.0, SIGMA_MM, 1.0, None, 0.25, 0.5))
    assert (law.height_distance, law.height_gap_per_mm) == (0.25, 0.5 / 4.0)
    assert law.scaled(1.2).height.tolist() == [0.25, 0.125, 0.0]
    plain = FootprintLaw.of(GapLaw(60.0, 4.0, SIGMA_MM, 1.0))
    assert plain.height.tolist() == [1.0, 0.0, 0.0]
    # the widening per mm of gap, at the height's share of the gap
    wide = FootprintLaw.of(GapLaw(60.0, 4.0, SIGMA_MM, 1.0, None, 0.25, 0.5, 0.08))
    assert wide.height.tolist() == [0.25, 0.125, 0.04]


def calibration_descents(as_distance, as_gap, seed=0, widening=0.0):
    """Descents (gap 4 .. 0 mm) over contact points on the dome, counts of the module's
    law with the height terms given and the footprint `widening` per mm of gap, gains 1 +-
    15 %, noise 1 count: (v, dist, gap, height, gains)."""
    rng = np.random.default_rng(seed)
    taxels = dome_taxels().xyz_mm
    gains = rng.uniform(0.85, 1.15, len(taxels))
    xy = rng.uniform(-30, 30, (80, 2))
    contact = np.column_stack([xy, on_dome(xy[:, 0], xy[:, 1])])
    gaps = np.arange(4.0, -0.05, -0.2)
    point = np.repeat(contact, gaps.size, axis=0)
    gap = np.tile(gaps, len(contact))
    off = point[:, None, :] - taxels[None, :, :]
    dist, height = np.linalg.norm(off, axis=2), off[:, :, 2]
    d2 = off[:, :, 0] ** 2 + off[:, :, 1] ** 2 + as_distance * height**2
    g = gap[:, None] + as_gap * np.abs(height)
    law = np.exp(-0.5 * d2 / (SIGMA_MM * (1.0 + widening * g)) ** 2 - g / DECAY_MM)
    v = gains * 40.0 * law + rng.normal(0.0, 1.0, law.shape)
    return v, dist, gap, height, gains


@pytest.mark.parametrize("as_distance, as_gap", [(0.0, AS_GAP), (0.3, 0.6)])
def test_calibration_finds_how_the_height_difference_enters(as_distance, as_gap):
    v, dist, gap, height, gains = calibration_descents(as_distance, as_gap)
    fit = fit_skin(v, dist, gap, height)
    assert fit["height_form_gain"] > 0.01 * v.size  # kept: well over the criterion
    # the two trade off a little: within a tenth with 80 descents, heights of +-8 mm
    assert fit["height_as_distance"] == pytest.approx(as_distance, abs=0.1)
    assert fit["height_as_gap"] == pytest.approx(as_gap, abs=0.1)
    assert fit["sigma_mm"] == pytest.approx(SIGMA_MM, rel=0.03)
    assert fit["gap_decay_mm"] == pytest.approx(DECAY_MM, rel=0.05)
    assert fit["contact_counts"] == pytest.approx(40.0 * gains.mean(), rel=0.05)


def test_the_3d_distance_is_kept_unless_the_height_terms_explain_the_descents_better():
    """A skin of the 3D distance: its law comes back exactly as fitted without the height
    terms (they do not pay for themselves); without heights they are not tried."""
    v, dist, gap, height, _ = calibration_descents(1.0, 0.0)
    fit = fit_skin(v, dist, gap, height)
    plain = fit_skin(v, dist, gap)
    assert (fit["height_as_distance"], fit["height_as_gap"]) == (1.0, 0.0)
    assert fit["height_form_gain"] < 4.0 * np.log(v.size)  # not kept
    assert plain["height_form_gain"] == 0.0
    for key in ("contact_counts", "sigma_mm", "gap_decay_mm", "rms_counts"):
        assert fit[key] == plain[key]
    assert np.array_equal(fit["gain"], plain["gain"])


def test_a_form_that_removes_less_than_the_least_share_is_not_kept():
    """Half the height as distance and 0.3 as gap: on these descents the form removes
    0.6 % of the squared residuals, well past the information criterion's 2 ln(M T)
    per parameter but short of ``HEIGHT_FORM_MIN_FALL``: the 3D distance is kept."""
    from fruitcli.sensing.skin.calibrate import HEIGHT_FORM_MIN_FALL

    v, dist, gap, height, _ = calibration_descents(0.5, 0.3)
    fit = fit_skin(v, dist, gap, height)
    assert 4.0 * np.log(v.size) < fit["height_form_gain"] < HEIGHT_FORM_MIN_FALL * v.size
    assert (fit["height_as_distance"], fit["height_as_gap"]) == (1.0, 0.0)


class FirstFitHeld:
    """`model_kernel.fit_all` whose first call keeps each touch's point within 1e-3 grid
    units of its start (N9's point) moved by `shift` grid units along a: a first fit
    stuck in a local minimum there (with `hold`; else it only counts the calls)."""

    def __init__(self, fit_all, hold=True, shift=0.0):
        self.fit_all, self.calls, self.hold, self.shift = fit_all, 0, hold, shift

    def __call__(self, x0, lo, hi, *rest):
        if self.hold and not self.calls:
            lo, hi, x0 = lo.copy(), hi.copy(), x0.copy()
            x0[:, 0] += self.shift
            lo[:, :2], hi[:, :2] = x0[:, :2] - 1e-3, x0[:, :2] + 1e-3
        self.calls += 1
        self.fit_all(x0, lo, hi, *rest)


@pytest.mark.parametrize("point_xy", [(40.0, 3.0), (38.0, -4.0)])
def test_a_second_fit_that_explains_the_frame_far_better_is_kept(monkeypatch, point_xy):
    """A touch 2-4 mm past the dome's last column (x = 36 mm), 13-15 mm below its top, of
    a skin that takes the height as gap. Its first fit is held at N9's point on the top;
    every touch at the grid's edge then gets a second fit from a pitch out
    (`model_fit._mirror_spread`), whose chi^2 is lower by far more than ``MIRROR_KEEP``:
    its point, radius and residual are the touch's, those of the fit left free."""
    from fruitcli.sensing.detection import model_fit, model_kernel

    taxels = dome_taxels()
    point = np.array([*point_xy, on_dome(*point_xy)])
    frames = board_frames(taxels, gap_form_counts(taxels.xyz_mm, point, 150.0), n=5)
    form = GapLaw(60.0, DECAY_MM, SIGMA_MM, 1.0, None, 0.0, AS_GAP)
    free = locate(taxels, frames, heights=form)
    fit_all = model_kernel.fit_all
    monkeypatch.setattr(model_kernel, "fit_all", held := FirstFitHeld(fit_all))
    second = locate(taxels, frames, heights=form)
    assert held.calls == 2  # the first fits and the second
    monkeypatch.setattr(model_kernel, "fit_all", FirstFitHeld(fit_all))
    monkeypatch.setattr(model_fit, "MIRROR_KEEP", np.inf)
    first = locate(taxels, frames, heights=form)
    assert (second.fit == FIT_MODEL).all() and (first.fit == FIT_MODEL).all()
    assert second.residual == pytest.approx(free.residual, abs=0.01)
    assert (second.residual < first.residual - 0.5).all()
    err = np.linalg.norm(second.xyz_mm - point, axis=1)
    err_first = np.linalg.norm(first.xyz_mm - point, axis=1)
    assert err.mean() < err_first.mean() - 2.0
    assert (err <= 3.0 * second.pos_err_mm).all()


def test_of_a_touchs_second_fits_the_lowest_below_the_margin_is_kept():
    from fruitcli.sensing.detection.model_fit import MIRROR_KEEP, _kept_seconds

    k = np.array([0, 1, 1, 2, 3, 3])  # touches 1 and 3 tried along both axes
    m = MIRROR_KEEP
    d = np.array([-m - 0.1, -m - 1.0, -m - 2.0, -m + 0.1, np.inf, -3 * m])
    assert _kept_seconds(k, d, 5).tolist() == [0, 2, 5]


@pytest.mark.parametrize(
    "held, as_gap, calls", [(False, AS_GAP, 1), (True, AS_GAP, 2), (True, 0.0, 1)]
)
def test_a_touch_the_row_inwards_reads_is_fitted_again_only_for_a_gap_form_misfit(
    monkeypatch, held, as_gap, calls
):
    """A touch 3 mm inside the dome's last column (x = 36 mm) is read by the column before.
    Frames of its own gap-form law with little noise leave no misfit: no second fit. Held
    half a pitch inwards its fit leaves one (``MIRROR_MISFIT``): a skin that takes the
    height as gap fits it again; with the 3D distance the column before reads it, so
    not, and the held fit fails (``MAX_REDUCED_CHI2``)."""
    from fruitcli.sensing.detection import model_kernel

    taxels = dome_taxels()
    point = np.array([33.0, 3.0, on_dome(33.0, 3.0)])
    frames = board_frames(taxels, gap_form_counts(taxels.xyz_mm, point), noise=0.1, n=3)
    law = GapLaw(60.0, DECAY_MM, SIGMA_MM, 1.0, None, 0.0 if as_gap else 1.0, as_gap)
    fits = FirstFitHeld(model_kernel.fit_all, held, shift=-0.5)
    monkeypatch.setattr(model_kernel, "fit_all", fits)
    t = locate(taxels, frames, heights=law)
    assert fits.calls == calls
    assert held or (t.residual < 1.0).all()  # free: at its own law, no misfit
    # held with the 3D distance, the fit explains the frame too badly: N9's point
    assert ((t.fit == FIT_MODEL) == (not held or as_gap > 0)).all()
