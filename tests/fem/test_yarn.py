"""Yarn stretch: a bent plate's top-face yarn stretches by h / R (closed form)."""

import numpy as np
import pytest

from fruitcli.errors import GeometryError
from fruitcli.fem.yarn import (
    DEFAULT_MAX_STRETCH,
    YARN_COLUMNS,
    Track,
    follow_tracks,
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
    x, y, z = np.meshgrid(
        np.linspace(0, length, nx + 1),
        np.linspace(0, width, ny + 1),
        np.linspace(-thick / 2, thick / 2, nz + 1),
        indexing="ij",
    )
    nodes = np.c_[x.ravel(), y.ravel(), z.ravel()]
    idx = np.arange(len(nodes)).reshape(nx + 1, ny + 1, nz + 1)
    c = [
        idx[:-1, :-1, :-1],
        idx[1:, :-1, :-1],
        idx[1:, 1:, :-1],
        idx[:-1, 1:, :-1],
        idx[:-1, :-1, 1:],
        idx[1:, :-1, 1:],
        idx[1:, 1:, 1:],
        idx[:-1, 1:, 1:],
    ]
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
    write_csv(
        tmp_path / "tracks.csv",
        ["track", "axis", "index", "point", "x_mm", "y_mm", "z_mm"],
        [[3, "x", 2, k, *map(float, p)] for k, p in enumerate(pts)],
        comments=["mm"],
    )
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
    (row,), s, warnings = stretch_table(
        [Track(0, "x", 0, rest)], [moved[None]], max_stretch=0.15, pitch_mm=4.0
    )
    assert s[0, 0] == pytest.approx(0.10)
    assert local_stretch(rest, moved[None], 4.0)[0] == pytest.approx(0.20)
    assert row[6] == pytest.approx(20.0) and row[4] == pytest.approx(10.0)
    assert len(warnings) == 1 and "20.0 % over 4 mm" in warnings[0]
    assert f"{zigzag_amplitude(0.2, 4.0):.2f} mm at a 4 mm pitch" in warnings[0]
    # a track shorter than the pitch: its whole length
    assert local_stretch(rest[:5], moved[None, :5], 4.0)[0] == pytest.approx(0.20)


@pytest.mark.parametrize(
    "text, says",
    [
        ("track,axis,index,point,x_mm,y_mm\n0,x,0,0,1,2\n", "expected columns"),
        (
            "track,axis,index,point,x_mm,y_mm,z_mm\n0,x,0,0,1,2,zz\n0,x,0,1,1,2,3\n",
            "line 2: expected integers",
        ),
        (
            "track,axis,index,point,x_mm,y_mm,z_mm\n0,x,0,0,1,2,nan\n0,x,0,1,1,2,3\n",
            "line 2: expected axis x or y and finite",
        ),
        (
            "track,axis,index,point,x_mm,y_mm,z_mm\n0,q,0,0,1,2,3\n0,q,0,1,1,2,3\n",
            "line 2: expected axis x or y",
        ),
        (
            "track,axis,index,point,x_mm,y_mm,z_mm\n0,x,0,0,1,2,3\n",
            "track 0: expected at least 2 points",
        ),
        (
            "track,axis,index,point,x_mm,y_mm,z_mm\n0,x,0,0,1,2,3\n0,x,0,1,1\n",
            "line 3: expected integers",
        ),
        (
            "track,axis,index,point,x_mm,y_mm,z_mm\n0,x,0,0,1,2,3\n0,x,0,1,1,2,3\n",
            "track 0: zero length",
        ),
        ("", "no tracks"),
        ("track,axis,index,point,x_mm,y_mm,z_mm\n", "no track points"),
    ],
)
def test_bad_tracks_file_is_one_line_naming_it(tmp_path, text, says):
    path = tmp_path / "tracks.csv"
    path.write_text(text)
    with pytest.raises(GeometryError) as err:
        read_tracks(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: ") and says in msg and "\n" not in msg
    with pytest.raises(GeometryError, match="tracks file not found"):
        read_tracks(tmp_path / "none.csv")


def test_follow_tracks_warns_of_points_outside_the_mesh_in_one_line():
    """On a model of linear tets at rest: no stretch; a track with a point 0.5 mm above a
    plate of 0.5 mm elements (exactly meshed: no point of its surface lies outside) is
    named in one warning line with the file, the one inside is not."""
    from fruitcli.fem.corotational_model import Model

    nodes, tets = plate_tets(4.0, 2.0, 1.0, 0.5)
    model = Model.from_arrays(nodes, tets, 100.0, 0.45)
    xs = np.linspace(0.0, 4.0, 9)
    inside = Track(0, "y", 0, np.c_[xs, np.full_like(xs, 1.0), np.full_like(xs, 0.5)])
    above = Track(1, "y", 1, inside.points + [0.0, 0.0, 0.0])
    above.points[4, 2] = 1.0
    said = []

    def above_top(points, outside):  # mm above the plate's top face (z = 0.5)
        return np.where(outside > 0, points[:, 2] - 0.5, 0.0)

    rows, summary = follow_tracks(
        model, [inside, above], model.rest[None], 0.25, 4.0, above_top, said.append, "t.csv"
    )
    assert [r[4] for r in rows] == pytest.approx([0.0, 0.0], abs=1e-9)
    assert said == [
        "simulate: warning: 1 of 2 tracks of t.csv (tracks 1) have points off the body: 1 "
        "of 18 points, up to 0.50 mm farther outside the mesh than the surface it meshes; "
        "they follow by extrapolation (check t.csv or [mesh].size_mm)"
    ]
    assert summary["tracks_outside_mesh"] == [1] and summary["warnings"] == []
    assert summary["off_body_max_mm"] == pytest.approx(0.5)


# ------------------------------------------------------------------ through `fruit simulate`
BEND = {"length": 24.0, "clamp": 4.0, "width": 6.0, "thick": 2.0}


def bent_plate_scene(folder, theta_deg=90.0, extra="", tracks=True, size_mm=1.5):
    """A 32 x 6 x 2 mm p2 pad, its left 4 mm held and its right 4 mm carried by jig
    springs through `theta_deg` about an axis below it, so that the 24 mm between them
    bends downwards by that angle (a circular arc of radius R = 24 mm / theta when the
    curvature is uniform). Tracks along x over those 24 mm, at y = 0: track 0 on the top
    face, h = 1 mm above the mid-surface, track 1 on the mid-surface. Returns the scene."""
    lb, clamp, width, t = BEND["length"], BEND["clamp"], BEND["width"], BEND["thick"]
    lx, th = lb + 2 * clamp, np.deg2rad(theta_deg)
    radius = lb / th
    # the right strip: shifted back by lb, then turned by theta about the arc's centre
    pivot = [-lb / 2, 0.0, t / 2 - radius]
    shift = [-lb * np.cos(th), 0.0, lb * np.sin(th)]
    xs = np.linspace(-lb / 2, lb / 2, 49)
    if tracks:
        lines = ["track,axis,index,point,x_mm,y_mm,z_mm"] + [
            f"{k},y,{k},{n},{x:.6f},0.0,{z}"
            for k, z in enumerate([t, t / 2])
            for n, x in enumerate(xs)
        ]
        (folder / "tracks.csv").write_text("\n".join(lines) + "\n")
    path = folder / "bend.toml"
    path.write_text(f"""
[scene]
name = "bend"
[geometry]
pad_size_mm = [{lx}, {width}, {t}]
[tracks]
file = "tracks.csv"
{extra}
[mesh]
size_mm = {size_mm}
[fem]
element = "p2"
[[fixed]]
box_mm = [{-lx / 2 - 1}, {-width}, -1.0, {-lb / 2}, {width}, {t + 1}]
[[jig]]
region_box_mm = [{lb / 2}, {-width}, -1.0, {lx / 2 + 1}, {width}, {t + 1}]
rotate_deg = {theta_deg}
axis = [0.0, 1.0, 0.0]
pivot_mm = [{pivot[0]}, {pivot[1]}, {pivot[2]}]
translate_mm = [{shift[0]}, {shift[1]}, {shift[2]}]
[solver]
jig_steps = 6
""")
    return path


@pytest.fixture(scope="module")
def bent(tmp_path_factory):
    """`fruit simulate` of the bent plate (90 degrees) with yarn_max_stretch 0.05 and two
    taxels on the top track (x = -4 and 4 mm)."""
    from click.testing import CliRunner

    from fruitcli.cli.main import cli

    folder = tmp_path_factory.mktemp("bent")
    scene = bent_plate_scene(folder, 90.0, "yarn_max_stretch = 0.05")
    (folder / "taxels.csv").write_text("id,i,j,x_mm,y_mm,z_mm\n0,0,0,-4,0,2\n1,1,0,4,0,2\n")
    res = CliRunner().invoke(
        cli,
        [
            "simulate",
            str(scene),
            "--out",
            str(folder / "o"),
            "--taxels",
            str(folder / "taxels.csv"),
        ],
    )
    assert res.exit_code == 0, res.output
    return folder, res


def test_simulate_bent_plate_top_yarn_stretches_h_over_r(bent):
    """Through the FEM: the top-face yarn stretches by h / R relative to the mid-surface
    yarn (h = 1 mm, R = 24 mm / (pi / 2): 6.54 %) within 5 %."""
    from fruitcli.tables import read_table

    folder, _ = bent
    yarns = read_table(folder / "o" / "yarns.csv", [c for c in YARN_COLUMNS if c != "axis"])
    assert list(yarns["track"]) == [0, 1]
    assert yarns["rest_length_mm"] == pytest.approx([24.0, 24.0])
    top, mid = 1 + yarns["max_stretch_pct"] / 100
    h, radius = BEND["thick"] / 2, BEND["length"] / (np.pi / 2)
    assert top / mid - 1 == pytest.approx(h / radius, rel=0.05)
    assert abs(mid - 1) < 0.01  # the mid-surface hardly stretches
    assert yarns["max_local_stretch_pct"][0] >= yarns["max_stretch_pct"][0]


def test_simulate_yarn_follows_the_quadratic_elements_as_the_taxels(bent):
    """yarns.csv's stretch is that of the track's points moved by the p2 shape functions
    (which move the taxels too), not by the corner tets' linear interpolation."""
    from fruitcli.fem.elements.barycentric import locate
    from fruitcli.fem.elements.lagrange import tet_shape
    from fruitcli.fem.yarn import polyline_lengths
    from fruitcli.tables import read_table

    folder, _ = bent
    st = np.load(folder / "o" / "states.npz")
    assert str(st["element"]) == "p2" and st["elements"].shape[1] == 10
    x = st["rest_nodes"] + st["displacement_mm"][-1]
    top = read_tracks(folder / "tracks.csv")[0].points
    tet, w, _ = locate(st["rest_nodes"], st["tets"], np.r_[top, [[-4.0, 0, 2], [4.0, 0, 2]]])
    quad = np.einsum("tai,ta->ti", x[st["elements"][tet]], tet_shape(w, 2))
    lin = np.einsum("tai,ta->ti", x[st["tets"][tet]], w)
    assert quad[-2:] == pytest.approx(st["taxels_mm"][-1], abs=1e-9)
    yarns = read_table(folder / "o" / "yarns.csv", ["max_stretch_pct"])
    s_quad = 100 * (polyline_lengths(quad[:-2]) / 24.0 - 1)
    s_lin = 100 * (polyline_lengths(lin[:-2]) / 24.0 - 1)
    assert yarns["max_stretch_pct"][0] == pytest.approx(s_quad, abs=1e-5)
    assert abs(s_lin - s_quad) > 1e-3


def test_simulate_warns_of_an_overstretched_track(bent):
    """yarn_max_stretch 0.05: the top yarn (about 6.5 %) is warned about on stderr, one
    line with the zig-zag that gives its slack; the mid-surface one is not."""
    from fruitcli.tables import read_table

    folder, res = bent
    warned = [line for line in res.stderr.splitlines() if "yarn_max_stretch" in line]
    assert len(warned) == 1 and "warning: track 0 " in warned[0]
    local = read_table(folder / "o" / "yarns.csv", ["max_local_stretch_pct"])[
        "max_local_stretch_pct"
    ][0]
    assert f"stretches {local:.1f} % over 4 mm" in warned[0]
    assert (
        f"zig-zag of amplitude {zigzag_amplitude(local / 100, 4.0):.2f} mm at a 4 mm "
        "pitch" in warned[0]
    )
    assert "1 over [tracks] yarn_max_stretch 5 %" in res.stdout


@pytest.mark.parametrize(
    "extra, says",
    [
        ("yarn_max_stretch = 0.0", "[tracks].yarn_max_stretch: expected a fraction 0 < value < 1"),
        ("yarn_max_stretch = 25", "[tracks].yarn_max_stretch: expected a fraction 0 < value < 1"),
        ("zigzag_pitch_mm = -1", "[tracks].zigzag_pitch_mm: expected > 0"),
    ],
)
def test_simulate_refuses_bad_yarn_settings(tmp_path, fruit, extra, says):
    res = fruit("simulate", bent_plate_scene(tmp_path, extra=extra), "--out", tmp_path / "o")
    assert res.exit_code == 1 and says in res.output.strip().splitlines()[-1]
    assert not (tmp_path / "o").exists()


def test_simulate_refuses_a_missing_or_malformed_tracks_file(tmp_path, fruit):
    scene = bent_plate_scene(tmp_path, tracks=False)
    res = fruit("simulate", scene, "--out", tmp_path / "o")
    assert res.exit_code == 1
    assert (
        res.output.strip().splitlines()[-1]
        == "Error: bend.toml: [tracks].file: file not found: tracks.csv"
    )
    (tmp_path / "tracks.csv").write_text("track,axis,index,point,x_mm,y_mm,z_mm\n0,x,0,0,1\n")
    res = fruit("simulate", scene, "--out", tmp_path / "o")
    assert res.exit_code == 1 and "Traceback" not in res.output
    assert (
        res.output.strip()
        .splitlines()[-1]
        .startswith(f"Error: {tmp_path / 'tracks.csv'}: line 2: expected integers")
    )
    assert not (tmp_path / "o").exists()


def test_planner_reruns_simulate_for_new_tracks_or_limits(tmp_path):
    """The simulate stage hashes the tracks file and the yarn settings and declares
    yarns.csv; make-tracks does not depend on the yarn settings."""
    from fruitcli.scene import load_scene
    from fruitcli.workflow.planner import Context, fingerprint
    from fruitcli.workflow.stages import STAGES

    stage = {s.name: s for s in STAGES}
    scene_path = bent_plate_scene(tmp_path)
    ctx = Context(tmp_path / "out")

    def prints(extra=""):
        sc = load_scene(bent_plate_scene(tmp_path, extra=extra, tracks=False))
        return fingerprint(stage["simulate"], sc, ctx), fingerprint(stage["make-tracks"], sc, ctx)

    sim0, tracks0 = prints()
    assert "yarns.csv" in stage["simulate"].outputs(load_scene(scene_path))
    sim1, tracks1 = prints("yarn_max_stretch = 0.2")
    assert sim1 != sim0 and tracks1 == tracks0
    (tmp_path / "tracks.csv").write_text(
        (tmp_path / "tracks.csv").read_text() + "2,x,0,0,0,0,2\n2,x,0,1,0,1,2\n"
    )
    assert prints()[0] not in (sim0, sim1)
