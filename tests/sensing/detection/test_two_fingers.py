"""fit2: two footprints of the skin fitted around each peak separate fingers that the
paper's N9 multitouch merges, and leaves single touches where N9 puts them."""

from dataclasses import dataclass

import numpy as np
import pytest

from fruitcli.sensing.detection.frames_to_touches import Locator
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.detection.two_footprints import Footprint, bilinear_window
from fruitcli.sensing.frames.board import default_board
from fruitcli.sensing.skin import forward
from fruitcli.sensing.skin.heights import GapLaw
from fruitcli.tables import Taxels

SIGMA = forward.default_footprints_mm()["small"]
LAW = GapLaw(60.0, 2.0, SIGMA, 1.0)


def grid_taxels() -> Taxels:
    i, j = np.divmod(np.arange(21 * 12), 12)
    return Taxels(np.arange(i.size), i, j, np.stack([16.0 * i, 12.0 * j, 0.0 * i], axis=1))


def frame(taxels, points) -> np.ndarray:
    v = sum(
        forward.activation_counts(
            np.linalg.norm(taxels.xyz_mm - np.asarray(p), axis=1)[None], np.zeros(1), "small"
        )[0]
        for p in points
    )
    return np.round(500.0 + v).astype(np.int64).reshape(1, 21, 12)  # counts, as boards give


def located(points, method):
    taxels = grid_taxels()
    loc = Locator(taxels, default_board(), taxels.xyz_mm, Settings(method=method), heights=LAW)
    return loc.batch(frame(taxels, points), np.full(252, 500.0))


def test_footprint_widths_in_pitches():
    tx = grid_taxels()
    fp = Footprint.from_taxels(SIGMA, 1.0, tx.i, tx.j, tx.xyz_mm)
    assert (fp.sigma_i, fp.sigma_j) == pytest.approx((SIGMA / 16.0, SIGMA / 12.0), rel=1e-12)


def test_bilinear_window_places_a_grid_point_exactly():
    tx = grid_taxels()
    from fruitcli.sensing.detection.detect import Grid

    grid = Grid.from_ij(tx.i, tx.j)
    tax, w, _ = bilinear_window(7.3, 4.6, grid)
    assert w.sum() == pytest.approx(1.0)
    p = w @ tx.xyz_mm[np.maximum(tax, 0)]
    assert p == pytest.approx([16.0 * 7.3, 12.0 * 4.6, 0.0], abs=1e-12)


@pytest.mark.parametrize("offset", [(16.0, 12.0), (16.0, 0.0), (0.0, 12.0)])
def test_fingers_one_pitch_apart_two_touches_near_their_truth(offset):
    """One pitch apart along i, j or the diagonal: N9 gives one touch (half the
    separation from each finger), fit2 two, each within a quarter of the separation of
    its finger (counts rounded, no noise; along i the footprint is 0.39 pitches wide, the
    narrowest, and the fit least sure)."""
    c = np.array([160.0 + 3.0, 66.0 - 2.0, 0.0])
    d = np.array([*offset, 0.0]) / 2
    truth = np.stack([c - d, c + d])
    assert len(located(truth, "n9")) == 1
    t = located(truth, "fit2")
    assert len(t) == 2
    err = np.linalg.norm(t.xyz_mm[:, None] - truth[None], axis=2).min(axis=1)
    assert err.max() < 0.25 * np.linalg.norm(2 * d)


def test_a_single_finger_is_where_n9_puts_it():
    rng = np.random.default_rng(2)
    for _ in range(10):
        p = [rng.uniform(40, 280), rng.uniform(20, 110), 0.0]
        a, b = located([p], "n9"), located([p], "fit2")
        assert len(a) == len(b) == 1
        assert (a.i[0], a.j[0], a.peak[0]) == (b.i[0], b.j[0], b.peak[0])
        np.testing.assert_allclose(a.xyz_mm, b.xyz_mm, rtol=0, atol=1e-9)


@pytest.mark.slow
def test_fingers_at_the_board_edges_stay_on_the_grid():
    """Up to four fingers anywhere, at corners and past the edges too (noisy counts): no
    footprint is placed off the taxel grid (it would have no taxels to weigh), every
    touch's weights stay a partition of one, its point lies among the taxels and its
    strength is finite."""
    rng = np.random.default_rng(3)
    taxels = grid_taxels()
    n = 1500
    r, c = np.meshgrid(np.arange(21), np.arange(12), indexing="ij")
    f = 500.0 + rng.normal(0, 2.0, (n, 21, 12))
    for _ in range(4):
        on = rng.random(n) < 0.6
        ci, cj = rng.uniform(-1, 21, n)[:, None, None], rng.uniform(-1, 12, n)[:, None, None]
        amp = rng.uniform(10, 90, n)[:, None, None]
        f += on[:, None, None] * amp * np.exp(-((r - ci) ** 2 + (c - cj) ** 2) / 1.1)
    loc = Locator(taxels, default_board(), taxels.xyz_mm, Settings(method="fit2"), heights=LAW)
    t = loc.batch(np.round(f).astype(np.int64), np.full(252, 500.0))
    assert len(t) > n
    assert (t.i >= 0).all() and (t.i <= 20).all() and (t.j >= 0).all() and (t.j <= 11).all()
    assert (t.xyz_mm[:, 0] >= 0).all() and (t.xyz_mm[:, 0] <= 320).all()
    assert (t.xyz_mm[:, 1] >= 0).all() and (t.xyz_mm[:, 1] <= 132).all()
    assert np.isfinite(t.strength).all()


WIDE_MM = 9.0  # a footprint with heavier tails than a Gaussian: (1 + (d / w)^2)^-1.5


@dataclass(frozen=True)
class WideLaw(GapLaw):
    """A skin whose footprint is not Gaussian (as the crossing table's is not)."""

    def contact_counts(self, taxel, dist_mm):
        return self.contact * (1.0 + (np.asarray(dist_mm) / WIDE_MM) ** 2) ** -1.5


@pytest.mark.parametrize("offset", [(16.0, 0.0), (0.0, 12.0), (16.0, 12.0), (8.0, 6.0)])
def test_fit2_fits_the_skins_own_footprint_not_a_gaussian(offset):
    """Two fingers of a skin whose footprint has heavy tails: fit2 given that law finds
    both within 0.4 mm; assuming a Gaussian of the same half-width instead, it misses
    them by millimetres (or merges them). The law's width sigma_mm only sets how far the
    profile is sampled."""
    taxels = grid_taxels()
    points = [np.array([80.0, 60.0, 0.0]), np.array([80.0 + offset[0], 60.0 + offset[1], 0.0])]
    v = sum(
        60.0 * (1.0 + (np.linalg.norm(taxels.xyz_mm - p, axis=1) / WIDE_MM) ** 2) ** -1.5
        for p in points
    )
    frames = np.round(500.0 + v).astype(np.int64).reshape(1, 21, 12)
    half_width = 0.651 * WIDE_MM  # the Gaussian sigma with the same half maximum

    def errors(law):
        loc = Locator(taxels, default_board(), taxels.xyz_mm, Settings(method="fit2"), heights=law)
        t = loc.batch(frames, np.full(252, 500.0))
        return len(t), [np.linalg.norm(t.xyz_mm - p, axis=1).min() for p in points]

    wide = Locator(
        taxels,
        default_board(),
        taxels.xyz_mm,
        Settings(method="fit2"),
        heights=WideLaw(60, 2, 6, 1),
    )
    assert wide.footprint.profile is not None
    gauss = Locator(taxels, default_board(), taxels.xyz_mm, Settings(method="fit2"), heights=LAW)
    assert gauss.footprint.profile is None  # the Gaussian law: its closed form
    n, err = errors(WideLaw(60.0, 2.0, half_width, 1.0))
    assert n == 2 and max(err) < 0.4
    _, gauss = errors(GapLaw(60.0, 2.0, half_width, 1.0))
    assert min(gauss) > 3.0


def test_fit2_without_a_footprint_law_is_one_error_naming_the_method():
    from fruitcli.errors import FrameError

    taxels = grid_taxels()
    with pytest.raises(FrameError, match=r'method = "fit2": the skin has no footprint law'):
        Locator(
            taxels,
            default_board(),
            taxels.xyz_mm,
            Settings(method="fit2"),
            heights=GapLaw(60.0, 2.0, np.nan, 1.0),
        )
