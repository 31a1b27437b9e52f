"""The flat pad's yarns are its grid lines: pad-grid writes them (tracks.csv) and the
simulate stage follows them (yarns.csv), as for an artist's tracks. On the bundled
touchpad, bent 180 degrees with its top face inside, the yarns across the bend shorten by
the closed form of a bent plate: -h/R on the bend, -h theta / L over the whole line."""

from __future__ import annotations

import numpy as np
import pytest

from fruitcli.fem.yarn import YARN_COLUMNS, polyline_lengths, read_tracks
from fruitcli.geometry.padgrid import pad_tracks, write_pad_tracks
from tests.conftest import ROOT

H_MM = 1.5  # the top face above the mid-surface of the 3 mm pad
BENT_MM = 49.0  # between the clamp (x < -24.5) and the jig (x > 24.5)
RADIUS_MM = BENT_MM / np.pi  # the scene's bend radius, 15.6 mm


def test_pad_tracks_are_the_grid_lines_edge_to_edge(tmp_path):
    rows = pad_tracks([80.0, 60.0, 3.0], [4, 3], 16.0, 20.0)
    tracks = {}
    for t, axis, index, point, x, y, z in rows:
        tracks.setdefault((t, axis, index), []).append((point, x, y, z))
    assert list(tracks) == [
        (0, "x", 0),
        (1, "x", 1),
        (2, "x", 2),
        (3, "x", 3),
        (4, "y", 0),
        (5, "y", 1),
        (6, "y", 2),
    ]
    line = np.array(tracks[1, "x", 1])
    assert line[:, 0].tolist() == list(range(len(line)))
    assert np.all(line[:, 1] == -8.0) and np.all(line[:, 3] == 3.0)  # x = -8 through i = 1
    assert line[0, 2] == -30.0 and line[-1, 2] == 30.0 and np.diff(line[:, 2]).max() <= 0.5
    line = np.array(tracks[6, "y", 2])
    assert np.all(line[:, 2] == 20.0) and line[0, 1] == -40.0 and line[-1, 1] == 40.0
    assert write_pad_tracks(tmp_path / "tracks.csv", [80.0, 60.0, 3.0], [4, 3], 16.0, 20.0) == 7
    read = read_tracks(tmp_path / "tracks.csv")
    assert [t.axis for t in read] == ["x"] * 4 + ["y"] * 3
    assert polyline_lengths(read[0].points) == pytest.approx(60.0)


@pytest.fixture(scope="module")
def touchpad(tmp_path_factory):
    from click.testing import CliRunner

    from fruitcli.cli.main import cli

    out = tmp_path_factory.mktemp("touchpad") / "out"
    res = CliRunner().invoke(
        cli, ["run", str(ROOT / "pipelines" / "touchpad-4x4.toml"), "--out", str(out)]
    )
    assert res.exit_code == 0, res.output
    return out


@pytest.mark.slow
def test_touchpad_yarns_across_the_bend_shorten_by_h_over_r(touchpad):
    from fruitcli.fem.elements.barycentric import locate
    from fruitcli.fem.elements.lagrange import tet_shape
    from fruitcli.tables import read_table

    yarns = read_table(
        touchpad / "simulate" / "yarns.csv", [c for c in YARN_COLUMNS if c != "axis"]
    )
    assert list(yarns["track"]) == list(range(8))
    assert yarns["rest_length_mm"] == pytest.approx([80.0] * 8)
    across, along = yarns["max_stretch_pct"][4:], yarns["max_stretch_pct"][:4]
    # the lines y = const run across the bend: the whole line shortens by h theta / L
    assert across / 100 == pytest.approx([-H_MM * np.pi / 80.0] * 4, rel=0.05)
    assert np.abs(along).max() < 1.0  # x = const lines lie along the bend axis
    # in the middle of the bend (|x| <= 16 mm) the top face shortens by h / R (9.6 %)
    st = np.load(touchpad / "simulate" / "states.npz")
    x = st["rest_nodes"] + st["displacement_mm"][-1]
    for track in read_tracks(touchpad / "pad-grid" / "tracks.csv")[4:]:
        rest = track.points[np.abs(track.points[:, 0]) <= 16.0]
        tet, w, _ = locate(st["rest_nodes"], st["tets"], rest)
        bent = np.einsum("tai,ta->ti", x[st["elements"][tet]], tet_shape(w, 2))
        strain = polyline_lengths(bent) / polyline_lengths(rest) - 1
        assert strain == pytest.approx(-H_MM / RADIUS_MM, rel=0.05), track.track
