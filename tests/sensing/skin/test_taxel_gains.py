"""Gains from the samples right over the taxels (`taxel_gains`): the same whatever the
footprint's law, which taxels count as over, and how they join the fitted gains."""

import numpy as np
import pytest

from fruitcli.sensing.skin.taxel_gains import OVER_TAXEL_MM, combine, gains_over_taxels

TAXELS = np.array([[16.0 * k, 0.0, 3.0] for k in range(5)])
GAINS = np.array([0.8, 1.1, 1.0, 1.25, 0.85])


def descents(law, threshold=20.0, step=0.1, start=5.0):
    """Frames of a descent over each taxel and one half a pitch off the first: (v (M, T),
    contact (M, 3), gaps (M,)); each descent stops at the first frame over the threshold,
    so a taxel of larger gain stops higher."""
    v, contact, gaps = [], [], []
    points = [*TAXELS, TAXELS[0] + [8.0, 6.0, 0.0]]
    for p in points:
        d = np.linalg.norm(TAXELS - p, axis=1)
        for gap in np.arange(start, -1.0, -step):
            a = GAINS * law(d, gap)
            v.append(a)
            contact.append(p)
            gaps.append(gap)
            if a.max() > threshold:
                break
    return np.array(v), np.array(contact), np.array(gaps)


def gaussian(d, gap):
    return 60.0 * np.exp(-0.5 * (d / 6.0) ** 2) * np.exp(-gap / 2.0)


def heavy(d, gap):
    return 90.0 / (1.0 + (d / 8.0) ** 2) ** 1.5 / (1.0 + gap) ** 2


@pytest.mark.parametrize("law", [gaussian, heavy])
def test_the_gains_over_the_taxels_do_not_depend_on_the_law(law):
    gain, over = gains_over_taxels(*descents(law), TAXELS)
    assert over.all()
    assert gain == pytest.approx(GAINS / GAINS.mean(), rel=1e-9)


def test_a_sample_just_off_a_taxel_is_not_over_it():
    v, contact, gaps = descents(gaussian)
    moved = contact.copy()
    moved[np.all(contact == TAXELS[2], axis=1), 0] += 1.01 * OVER_TAXEL_MM
    gain, over = gains_over_taxels(v, moved, gaps, TAXELS)
    assert over.tolist() == [True, True, False, True, True] and np.isnan(gain[2])
    rest = np.array([0, 1, 3, 4])
    assert gain[rest] == pytest.approx(GAINS[rest] / GAINS[rest].mean(), rel=1e-9)


def test_fewer_than_two_taxels_over_give_none():
    v, contact, gaps = descents(gaussian)
    keep = np.all(contact == TAXELS[0], axis=1)
    gain, over = gains_over_taxels(v[keep], contact[keep], gaps[keep], TAXELS)
    assert not over.any() and np.isnan(gain).all()
    assert not gains_over_taxels(v[:0], contact[:0], gaps[:0], TAXELS)[1].any()


def test_combine_scales_the_gains_over_to_the_fitted_ones():
    fitted = np.array([1.2, 0.9, 1.0, 1.0])
    measured = np.array([True, True, True, False])
    gain = np.array([2.0, 1.0, np.nan, 3.0])
    over = np.array([True, True, False, True])
    out, now, factor = combine(fitted, measured, gain, over)
    # scaled by the fitted mean over taxels 0 and 1 (1.05) over theirs (1.5): 0.7
    scaled = np.array([1.4, 0.7, 1.0, 2.1])
    assert now.tolist() == [True, True, True, True]
    assert factor == pytest.approx(scaled.mean())
    assert out == pytest.approx(scaled / scaled.mean())
