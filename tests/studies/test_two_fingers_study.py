"""fruit study two-fingers: the grid's bodies at rest and deformed, the points between
taxels, and the table's rows."""

import numpy as np
import pytest

from fruitcli.studies import two_fingers as tf


def test_bodies_keep_their_lengths_along_the_surface():
    rest = tf.body_taxels("rest").reshape(21, 12, 3)
    assert np.diff(rest[:, 0, 0]) == pytest.approx(np.full(20, 16.0))
    assert np.diff(rest[0, :, 1]) == pytest.approx(np.full(11, 12.0))
    bent = tf.body_taxels("bent").reshape(21, 12, 3)
    r = tf.BEND_RADIUS_MM
    chord_i = np.linalg.norm(np.diff(bent[:, 0], axis=0), axis=1)
    assert chord_i == pytest.approx(np.full(20, 2 * r * np.sin(8.0 / r)), rel=1e-12)
    assert np.linalg.norm(np.diff(bent[0], axis=0), axis=1) == pytest.approx(np.full(11, 12.0))
    dome = tf.body_taxels("stretched")
    r = tf.DOME_RADIUS_MM
    assert np.linalg.norm(dome - [0, 0, -r], axis=1) == pytest.approx(np.full(252, r))
    # geodesic (great-circle) distance of each taxel from the top: stretched arc length
    i, j = np.divmod(np.arange(252), 12)
    arc = tf.STRETCH * np.hypot(16.0 * (i - 10), 12.0 * (j - 5.5))
    cos = np.clip((dome + [0, 0, r]) @ [0, 0, 1] / r, -1, 1)
    assert r * np.arccos(cos) == pytest.approx(arc, rel=1e-9)


def test_surface_points_are_the_taxels_at_whole_coordinates_and_between_them_bilinear():
    pos = tf.body_taxels("bent")
    i, j = np.divmod(np.arange(252), 12)
    assert tf.surface_points(pos, i.astype(float), j.astype(float)) == pytest.approx(pos)
    mid = tf.surface_points(pos, np.array([3.5]), np.array([7.0]))[0]
    assert mid == pytest.approx((pos[3 * 12 + 7] + pos[4 * 12 + 7]) / 2)
    with pytest.raises(ValueError, match="body: expected"):
        tf.body_taxels("twisted")


def test_rows_per_body_axis_distance_and_method():
    rows, singles = tf.run(trials=6, singles=12, distances=(0.5, 3.0), bodies=("rest", "bent"))
    assert len(rows) == 2 * 3 * 2 * 2
    assert {r[0] for r in rows} == {"rest", "bent"}
    for r in rows:
        assert 0 <= r[6] + r[7] + r[8] <= 1
    far = [r for r in rows if r[2] == 3.0]
    assert np.mean([r[6] for r in far]) > 0.8  # three pitches apart: two touches
    # half a pitch apart along i: N9 merges them on every body
    assert all(r[6] == 0 for r in rows if r[2] == 0.5 and r[1] == "i" and r[4] == "n9")
    assert [(b, m) for b, m, *_ in singles] == [
        ("rest", "n9"),
        ("rest", "fit2"),
        ("bent", "n9"),
        ("bent", "fit2"),
    ]
    text = tf.markdown(rows, singles)
    assert "## Body bent on a cylinder" in text and "## Body at rest" in text
