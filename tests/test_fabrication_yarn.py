"""Yarn stretch: a bent plate's top-face yarn stretches by h / R (closed form)."""

import numpy as np
import pytest

from fruitcli.errors import GeometryError
from fruitcli.fabrication.yarn import (
    DEFAULT_MAX_STRETCH,
    YARN_COLUMNS,
    Track,
    local_stretch,
    read_tracks,
    stretch_table,
    write_yarns_csv,
    yarn_stretch,
    zigzag_amplitude,
)


def plate_tets(length, width, thick, step):
    """A structured tet mesh of [0, length] x [0, width] x [-thick/2, thick/2] (6 tets per
    cube)."""
    nx, ny, nz = (int(round(v / step)) for v in (length, width, thick))
    x, y, z = np.meshgrid(np.linspace(0, length, nx + 1), np.linspace(0, width, ny + 1),
                          np.linspace(-thick / 2, thick / 2, nz + 1), indexing="ij")
    nodes = np.c_[x.ravel(), y.ravel(), z.ravel()]
    idx = np.arange(len(nodes)).reshape(nx + 1, ny + 1, nz + 1)
    c = [idx[:-1, :-1, :-1], idx[1:, :-1, :-1], idx[1:, 1:, :-1], idx[:-1, 1:, :-1],
         idx[:-1, :-1, 1:], idx[1:, :-1, 1:], idx[1:, 1:, 1:], idx[:-1, 1:, 1:]]
    c = [a.ravel() for a in c]
    six = [(0, 1, 2, 6), (0, 2, 3, 6), (0, 3, 7, 6), (0, 7, 4, 6), (0, 4, 5, 6), (0, 5, 1, 6)]
    tets = np.concatenate([np.c_[c[a], c[b], c[d], c[e]] for a, b, d, e in six])
    return nodes, tets


def bend(nodes, radius):
    """Bend about the y axis: the mid-surface z = 0 follows a circle of radius `radius`."""
    x, y, z = nodes.T
    a = x / radius
    return np.c_[(radius + z) * np.sin(a), y, (radius + z) * np.cos(a) - radius] - nodes


def test_bent_pad_stretches_top_yarn_by_h_over_r():
    """The 4 x 4 pad's 48 mm active length bent 180 degrees: R = 48 / pi; a yarn on the
    top face, h = 1.5 mm above the mid-surface, stretches by h / R (9.8 %) within 5 %;
    one on the mid-surface does not stretch."""
    length, h = 48.0, 1.5
    nodes, tets = plate_tets(length, 12.0, 2 * h, 0.5)
    r = length / np.pi
    disp = np.stack([np.zeros_like(nodes), bend(nodes, 2 * r), bend(nodes, r)])
    xs = np.linspace(0.0, length, 97)
    top = Track(0, "y", 0, np.c_[xs, np.full_like(xs, 6.0), np.full_like(xs, h)])
    mid = Track(1, "y", 1, np.c_[xs, np.full_like(xs, 6.0), np.zeros_like(xs)])
    rows, s, warnings = yarn_stretch([top, mid], nodes, tets, disp)
    assert s[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert s[0, 2] == pytest.approx(h / r, rel=0.05)
    assert s[0, 1] == pytest.approx(h / (2 * r), rel=0.05)
    assert abs(s[1, 2]) < 0.005
    assert rows[0][3] == pytest.approx(length) and rows[0][5] == 2
    assert rows[0][4] == pytest.approx(100 * s[0, 2])
    assert warnings == []
    _, _, warnings = yarn_stretch([top], nodes, tets, disp, max_stretch=0.05)
    assert len(warnings) == 1 and "track 0" in warnings[0] and "zig-zag" in warnings[0]


def test_zigzag_amplitude_gives_the_slack():
    a = zigzag_amplitude(0.1, 4.0)
    assert np.sqrt(1 + (4 * a / 4.0) ** 2) - 1 == pytest.approx(0.1)
    assert zigzag_amplitude(0.0, 4.0) == 0.0
    assert DEFAULT_MAX_STRETCH == pytest.approx(0.25)


def test_yarns_csv_and_tracks_csv_round_trip(tmp_path):
    from fruitcli.fsutil import write_csv
    from fruitcli.tables import read_table

    pts = np.array([[0.0, 0, 0], [1, 0, 0], [1, 2, 0]])
    write_csv(tmp_path / "tracks.csv", ["track", "axis", "index", "point", "x_mm", "y_mm",
                                         "z_mm"],
              [[3, "x", 2, k, *map(float, p)] for k, p in enumerate(pts)], comments=["mm"])
    (t,) = read_tracks(tmp_path / "tracks.csv")
    assert (t.track, t.axis, t.index) == (3, "x", 2) and np.allclose(t.points, pts)
    write_yarns_csv(tmp_path / "yarns.csv", [[3, "x", 2, 3.0, 12.5, 4, 20.0, 1]])
    back = read_table(tmp_path / "yarns.csv", [c for c in YARN_COLUMNS if c != "axis"])
    assert back["max_stretch_pct"][0] == pytest.approx(12.5)
    assert back["max_local_stretch_pct"][0] == pytest.approx(20.0)


def test_local_stretch_is_the_largest_over_one_pitch():
    """A 20 mm track whose first half stretches 20 % and second half not at all: 10 %
    over its length, 20 % over any 4 mm of the first half."""
    xs = np.linspace(0.0, 20.0, 81)
    rest = np.c_[xs, np.zeros_like(xs), np.zeros_like(xs)]
    moved = rest.copy()
    moved[:, 0] = np.where(xs <= 10, 1.2 * xs, 12.0 + (xs - 10))
    (row,), s, warnings = stretch_table([Track(0, "x", 0, rest)], [moved[None]],
                                        max_stretch=0.15, pitch_mm=4.0)
    assert s[0, 0] == pytest.approx(0.10)
    assert local_stretch(rest, moved[None], 4.0)[0] == pytest.approx(0.20)
    assert row[6] == pytest.approx(20.0) and row[4] == pytest.approx(10.0)
    assert len(warnings) == 1 and "20.0 % over 4 mm" in warnings[0]
    assert f"{zigzag_amplitude(0.2, 4.0):.2f} mm at a 4 mm pitch" in warnings[0]
    # a track shorter than the pitch: its whole length
    assert local_stretch(rest[:5], moved[None, :5], 4.0)[0] == pytest.approx(0.20)


@pytest.mark.parametrize("text, says", [
    ("track,axis,index,point,x_mm,y_mm\n0,x,0,0,1,2\n", "expected columns"),
    ("track,axis,index,point,x_mm,y_mm,z_mm\n0,x,0,0,1,2,zz\n0,x,0,1,1,2,3\n",
     "line 2: expected integers"),
    ("track,axis,index,point,x_mm,y_mm,z_mm\n0,x,0,0,1,2,nan\n0,x,0,1,1,2,3\n",
     "line 2: expected axis x or y and finite"),
    ("track,axis,index,point,x_mm,y_mm,z_mm\n0,q,0,0,1,2,3\n0,q,0,1,1,2,3\n",
     "line 2: expected axis x or y"),
    ("track,axis,index,point,x_mm,y_mm,z_mm\n0,x,0,0,1,2,3\n", "track 0: expected at "
     "least 2 points"),
    ("track,axis,index,point,x_mm,y_mm,z_mm\n0,x,0,0,1,2,3\n0,x,0,1,1\n",
     "line 3: expected integers"),
    ("", "no tracks"),
    ("track,axis,index,point,x_mm,y_mm,z_mm\n", "no track points"),
])
def test_bad_tracks_file_is_one_line_naming_it(tmp_path, text, says):
    path = tmp_path / "tracks.csv"
    path.write_text(text)
    with pytest.raises(GeometryError) as err:
        read_tracks(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: ") and says in msg and "\n" not in msg
    with pytest.raises(GeometryError, match="tracks file not found"):
        read_tracks(tmp_path / "none.csv")
