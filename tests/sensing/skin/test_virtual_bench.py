"""Virtual bench, forward-model calibration targets and sensitivity on hand-built states."""

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import FrameError
from fruitcli.fem.elements.barycentric import locate
from fruitcli.fem.meshing.topology import boundary_faces
from fruitcli.scene import parse_scene
from fruitcli.sensing.detection.locate import load_states
from fruitcli.sensing.frames.recording import read_npz
from fruitcli.sensing.skin import forward
from fruitcli.sensing.skin.sensitivity import animation_shift, noise_std_counts
from fruitcli.sensing.stages import run_bench, run_sensitivity
from fruitcli.tables import read_table
from tests.helpers.locate import locate_scene

PAD_SCENE = """
[grid]
spacing_x_mm = 16.0
spacing_y_mm = 16.0
[bench]
indenters = ["small", "medium"]
seed = 3
"""


def pad_states(path: Path, angles_deg=(0.0, 90.0, 180.0)):
    """Flat 80 x 80 x 3 mm pad, 4 x 4 taxels on top, bent about y to each angle over its
    48 mm active length."""
    nodes, tets = forward.pad_mesh()
    taxels = forward.pad_taxels_mm(z_mm=3.0 - 1e-6)
    k, bary, _ = locate(nodes, tets, taxels)
    disp, tax = [], []
    for a in angles_deg:
        moved = nodes if a == 0 else forward.bend_nodes(nodes, 48.0 / np.radians(a), 3.0)
        disp.append(moved - nodes)
        tax.append(np.einsum("tk,tkd->td", bary, moved[tets[k]]))
    np.savez(
        path,
        rest_nodes=nodes,
        tets=tets,
        surface_tris=boundary_faces(nodes, tets),
        displacement_mm=np.array(disp),
        pressure_kpa=np.array(angles_deg)[:, None] / 90,
        chamber_names=np.array(["bend"]),
        taxels_mm=np.array(tax),
        taxel_tet=k,
        taxel_bary=bary,
    )
    return path


def pad_taxel_csv(path: Path):
    t = forward.pad_taxels_mm(z_mm=3.0)
    lines = ["# 4 x 4 pad taxels, mm", "id,i,j,x_mm,y_mm,z_mm"]
    for n, (x, y, z) in enumerate(t):
        lines.append(f"{n},{n // 4},{n % 4},{x},{y},{z}")
    path.write_text("\n".join(lines) + "\n")
    return path


def scene(tmp_path, extra=""):
    return parse_scene(PAD_SCENE + extra, tmp_path / "pad.toml", must_exist=False)


def test_bent_pad_calibration_gives_10_counts_at_180_deg(tmp_path):
    # the calibration rule: the most strained taxel of the pad bent 180 deg shifts 10 counts
    states = load_states(pad_states(tmp_path / "s.npz"))
    strain = forward.taxel_strain(states)
    unit = forward.Skin(np.zeros(16), np.zeros(16), np.ones(16))
    shift = forward.strain_shift_counts(strain, unit)
    assert shift[0] == pytest.approx(np.zeros(16), abs=1e-9)
    assert shift[2].max() == pytest.approx(forward.BEND_SHIFT_COUNTS, rel=1e-6)
    assert shift[1].max() < shift[2].max()  # a gentler bend shifts less


def test_noise_model_reaches_the_papers_1_9_counts():
    skin = forward.make_skin(47, seed=0)
    rng = np.random.default_rng(1)
    rest = forward.frame_counts(
        np.broadcast_to(skin.baseline_counts, (300, 47)), skin.noise_std_counts, rng
    )
    std = noise_std_counts(rest)
    assert 1.6 < std.max() <= 2.0 and std.min() > 0.3
    assert rest.dtype == np.int64


def test_activation_crosses_threshold_before_contact_and_medium_is_wider():
    gap = 2 * forward.GAP_DECAY_MM * np.log(3) / 2  # 60 exp(-g/2) = 20 at g = 2 ln 3
    v = forward.activation_counts(np.zeros((1, 1)), np.array([gap]), "small")
    assert v[0, 0] == pytest.approx(forward.THRESHOLD_COUNTS)
    far = forward.activation_counts(np.full((1, 1), 12.0), np.array([0.0]), "small")
    wide = forward.activation_counts(np.full((1, 1), 12.0), np.array([0.0]), "medium")
    assert wide > far


def test_animation_shift_interpolates_between_states():
    s = np.array([[0.0, 0.0], [10.0, 2.0], [0.0, 4.0]])
    a = animation_shift(s, 5)
    assert a[:, 0].tolist() == [0.0, 5.0, 10.0, 5.0, 0.0]


def test_bench_without_states_then_locate_recovers_the_samples(tmp_path):
    sc = scene(tmp_path)
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    res = run_bench(sc, taxels, None, tmp_path / "bench")
    # quarter offsets +4 mm: the last row and column fall off the taxels' hull
    assert res["off_surface"] == 7 and res["indenters"]["small"]["samples"] == 9
    rec = read_npz(tmp_path / "bench" / "small" / "frames.npz")
    assert rec.frames.shape[1:] == (21, 12) and rec.meta["state"] == 0
    truth = read_table(
        tmp_path / "bench" / "small" / "truth.csv", ["sample", "x_mm", "y_mm", "z_mm"]
    )
    assert np.sum(rec.sample >= 0) == len(truth["sample"])
    assert np.allclose(truth["z_mm"], 3.0)
    assert np.allclose((truth["x_mm"] + 24) % 16, 4.0)
    out = locate_scene(
        sc, tmp_path / "bench" / "small" / "frames.npz", taxels, None, tmp_path / "loc"
    )
    assert out["samples_missed"] == 0
    m = read_table(tmp_path / "loc" / "measured.csv", ["sample", "x_mm", "y_mm", "z_mm"])
    assert m["sample"].tolist() == truth["sample"].tolist()
    err = np.hypot(m["x_mm"] - truth["x_mm"], m["y_mm"] - truth["y_mm"])
    assert err.max() < 8.0 and err.mean() < 5.0  # N9 pulls towards the grid points


def test_locate_takes_the_baseline_over_every_idle_frame_of_the_bench(tmp_path):
    """A bench that records 40 idle frames: `fruit locate` with ``[detection]
    .baseline_frames`` left at 10 finds the touches it finds when told 40 (the meta's
    count), to the last digit."""
    sc = scene(tmp_path, "baseline_frames = 40\n")
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    run_bench(sc, taxels, None, tmp_path / "bench")
    frames = tmp_path / "bench" / "small" / "frames.npz"
    assert read_npz(frames).meta["baseline_frames"] == 40
    told = sc.with_values({"detection.baseline_frames": 40})
    locate_scene(sc, frames, taxels, None, tmp_path / "default")
    locate_scene(told, frames, taxels, None, tmp_path / "told")
    default = (tmp_path / "default" / "touches.csv").read_text()
    assert default == (tmp_path / "told" / "touches.csv").read_text()
    assert sc.detection.baseline_frames == 10


def test_bench_on_bent_states_truth_on_the_deformed_surface(tmp_path):
    sc = scene(tmp_path, "state = 2\n")
    states = pad_states(tmp_path / "s.npz")
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    res = run_bench(sc, taxels, states, tmp_path / "bench")
    assert res["indenters"]["small"]["samples"] > 0
    truth = read_table(
        tmp_path / "bench" / "small" / "truth.csv", ["sample", "x_mm", "y_mm", "z_mm"]
    )
    # the top of a cylinder of radius 48/pi + 1.5 mm around the axis z = 1.5 - R
    r = 48 / np.pi
    rad = np.hypot(truth["x_mm"], truth["z_mm"] - (1.5 - r))
    assert np.allclose(rad, r + 1.5, atol=0.2)  # faceted by 4 mm elements
    out = locate_scene(
        sc, tmp_path / "bench" / "small" / "frames.npz", taxels, states, tmp_path / "loc"
    )
    m = read_table(tmp_path / "loc" / "measured.csv", ["sample", "x_mm", "y_mm", "z_mm"])
    assert out["samples_missed"] == 0
    pts = np.column_stack([m["x_mm"], m["y_mm"], m["z_mm"]])
    tru = np.column_stack([truth["x_mm"], truth["y_mm"], truth["z_mm"]])
    err = np.linalg.norm(pts - tru, axis=1)
    # the same frames located on the rest taxels (no model) are much farther off
    locate_scene(sc, tmp_path / "bench" / "small" / "frames.npz", taxels, None, tmp_path / "r")
    r = read_table(tmp_path / "r" / "measured.csv", ["sample", "x_mm", "y_mm", "z_mm"])
    err_rest = np.linalg.norm(np.column_stack([r["x_mm"], r["y_mm"], r["z_mm"]]) - tru, axis=1)
    assert err.mean() < 5.0 and err_rest.mean() > err.mean() + 1.0


def test_sensitivity_json_and_heatmaps(tmp_path):
    sc = scene(tmp_path)
    out = run_sensitivity(
        sc, pad_taxel_csv(tmp_path / "t.csv"), pad_states(tmp_path / "s.npz"), tmp_path / "sens"
    )
    data = json.loads((tmp_path / "sens" / "sensitivity.json").read_text())
    assert len(data["taxels"]) == 16 and data["states"] == 3
    model = np.array([t["max_shift_model"] for t in data["taxels"]])
    fab = np.array([t["fab"] for t in data["taxels"]])
    assert (model / fab).max() == pytest.approx(10.0, rel=1e-6)
    assert np.all(fab == 1.0) and model.max() <= 10.0 + 1e-9  # seed 3: no defective crossing
    assert out["summary"]["std"]["max"] <= 2.0
    for name in ("noise_std.png", "max_shift.png", "noise_std_top.png", "max_shift_top.png"):
        assert (tmp_path / "sens" / name).read_bytes()[:4] == b"\x89PNG"


def test_bench_cli_bad_input(tmp_path):
    (tmp_path / "pad.toml").write_text(PAD_SCENE)
    res = CliRunner().invoke(
        cli, ["bench", str(tmp_path / "pad.toml"), "--out", str(tmp_path / "o")]
    )
    assert res.exit_code == 1 and "no taxels: give --taxels" in res.output
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    (tmp_path / "pad.toml").write_text(PAD_SCENE + "state = 1\n")
    res = CliRunner().invoke(
        cli,
        [
            "bench",
            str(tmp_path / "pad.toml"),
            "--taxels",
            str(taxels),
            "--out",
            str(tmp_path / "o"),
        ],
    )
    assert res.exit_code == 1 and "[bench].state = 1 needs FEM states" in res.output


def pad_surface_stl(path: Path):
    """The pad's closed boundary at rest (the body the bench touches), as an STL in mm."""
    import trimesh

    nodes, tets = forward.pad_mesh()
    trimesh.Trimesh(nodes, boundary_faces(nodes, tets), process=False).export(path)
    return path


def test_one_truth_a_state_with_zero_displacement_gives_the_rest_row(tmp_path):
    """The truth lies on the body's surface in every configuration: a FEM state that does
    not move the body (a jig rotated by 0 deg) gives the rest bench's truth, frames and
    Table I row."""
    from fruitcli.evaluation.report import evaluate_pair

    sc = scene(tmp_path)
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    surface = pad_surface_stl(tmp_path / "pad.stl")
    still = pad_states(tmp_path / "s.npz", angles_deg=(0.0,))
    rest = run_bench(sc, taxels, None, tmp_path / "rest", surface_path=surface)
    held = run_bench(sc, taxels, still, tmp_path / "held", surface_path=surface)
    assert "at rest" in rest["truth_surface"] and "carried by FEM state 0" in held["truth_surface"]
    # every quarter sample lies over the 80 x 80 mm body, also those past the taxels' hull
    assert rest["off_surface"] == held["off_surface"] == 0
    rows = {}
    for name, states in (("rest", None), ("held", still)):
        t = read_table(tmp_path / name / "small" / "truth.csv", ["sample", "x_mm", "y_mm", "z_mm"])
        assert np.allclose(t["z_mm"], 3.0, atol=1e-9)  # the pad's top face
        locate_scene(
            sc, tmp_path / name / "small" / "frames.npz", taxels, states, tmp_path / f"loc-{name}"
        )
        rows[name], _, truth, _ = evaluate_pair(
            tmp_path / name / "small" / "truth.csv", tmp_path / f"loc-{name}" / "measured.csv"
        )
        rows[name]["truth"] = truth
    np.testing.assert_allclose(rows["held"]["truth"], rows["rest"]["truth"], atol=1e-9)
    a = read_npz(tmp_path / "rest" / "small" / "frames.npz").frames
    b = read_npz(tmp_path / "held" / "small" / "frames.npz").frames
    assert np.array_equal(a, b)
    for key in ("n", "mean_mm", "std_mm", "max_mm"):
        assert rows["held"][key] == pytest.approx(rows["rest"][key], abs=1e-9)


def test_truth_on_a_bent_body_follows_the_carried_surface(tmp_path):
    sc = scene(tmp_path, "state = 1\n")
    surface = pad_surface_stl(tmp_path / "pad.stl")
    res = run_bench(
        sc,
        pad_taxel_csv(tmp_path / "t.csv"),
        pad_states(tmp_path / "s.npz", angles_deg=(0.0, 180.0)),
        tmp_path / "b",
        surface_path=surface,
    )
    truth = read_table(tmp_path / "b" / "small" / "truth.csv", ["sample", "x_mm", "y_mm", "z_mm"])
    assert res["indenters"]["small"]["samples"] > 0
    r = 48 / np.pi  # the mid-plane's bend radius; the top face lies 1.5 mm outside it
    rad = np.hypot(truth["x_mm"], truth["z_mm"] - (1.5 - r))
    assert np.allclose(rad, r + 1.5, atol=0.2)  # faceted by 4 mm elements


def test_skin_table_defaults_are_the_models_assumptions(tmp_path):
    p = forward.SkinParams.from_table(scene(tmp_path).skin)
    assert p == forward.DEFAULT_PARAMS
    assert p.footprint_sigma_mm == pytest.approx(
        {"small": np.hypot(6, 1.5), "medium": np.hypot(6, 4)}
    )
    assert (p.contact_counts, p.gap_decay_mm, p.gain_spread) == (60.0, 2.0, 0.0)
    assert p.noise_std_counts == (0.5, 1.85)


def test_skin_table_sets_the_touch_response(tmp_path):
    text = (
        "[skin]\nfootprint_sigma_mm = { small = 4.5 }\ncontact_counts = 80.0\n"
        "gap_decay_mm = 1.0\ngain_spread = 0.2\nnoise_std_counts = 1.2\n"
    )
    p = forward.SkinParams.from_table(scene(tmp_path, text).skin)
    assert p.footprint_sigma_mm["small"] == 4.5
    assert p.footprint_sigma_mm["medium"] == pytest.approx(np.hypot(6, 4))  # default kept
    plain = forward.make_skin(40, seed=5)
    skin = forward.make_skin(40, seed=5, params=p)
    # the other draws stay those of the default skin
    assert np.array_equal(skin.baseline_counts, plain.baseline_counts)
    assert np.array_equal(skin.fab, plain.fab) and np.all(skin.noise_std_counts == 1.2)
    assert plain.gain is None and np.all(np.abs(skin.gain - 1) <= 0.2) and skin.gain.std() > 0
    dist = np.stack([np.zeros(40), np.full(40, 4.5)])  # (2 steps, 40 taxels)
    v = forward.activation_counts(dist, np.array([0.0, 1.0]), "small", skin)
    g = skin.gain
    np.testing.assert_allclose(v[0], 80 * g)  # at contact, under the taxel
    np.testing.assert_allclose(v[1], 80 * np.exp(-0.5) * np.exp(-1.0) * g)  # 1 sigma, 1 decay


@pytest.mark.parametrize(
    "text,expected",
    [
        ("contact_counts = 0.0", "[skin].contact_counts: expected > 0"),
        ("gap_decay_mm = -1.0", "[skin].gap_decay_mm: expected > 0"),
        ("gain_spread = 1.5", "[skin].gain_spread: expected 0 <= spread < 1"),
        (
            "noise_std_counts = [2.0, 1.0]",
            "[skin].noise_std_counts: expected a number >= 0 or [lo, hi]",
        ),
        ("footprint_sigma_mm = { small = 0 }", "[skin].footprint_sigma_mm.small: expected a width"),
        ("contact_count = 60.0", "unknown key 'contact_count' (did you mean 'contact_counts'?)"),
    ],
)
def test_bad_skin_table_is_one_line(tmp_path, text, expected):
    from fruitcli.errors import SceneError

    with pytest.raises(SceneError) as info:
        scene(tmp_path, "[skin]\n" + text + "\n")
    assert expected in str(info.value)


def test_bench_reads_the_skin_table(tmp_path):
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    run_bench(scene(tmp_path), taxels, None, tmp_path / "a")
    run_bench(scene(tmp_path, "[skin]\ncontact_counts = 120.0\n"), taxels, None, tmp_path / "b")
    a = read_npz(tmp_path / "a" / "small" / "frames.npz")
    b = read_npz(tmp_path / "b" / "small" / "frames.npz")
    # a stronger touch crosses the threshold earlier: fewer approach frames
    assert len(b.frames) < len(a.frames)


def test_project_to_surface_moves_a_chord_point_onto_the_body(tmp_path):
    from fruitcli.geometry.body_surface import body_surface, project_to_surface

    surface = body_surface(pad_surface_stl(tmp_path / "pad.stl"))
    pts, dist = project_to_surface(
        np.array([[1.0, 2.0, 2.5], [0.0, 0.0, 3.4]]),
        surface,
        None,
        None,
        forward.pad_taxels_mm(z_mm=3.0),
    )
    np.testing.assert_allclose(pts, [[1.0, 2.0, 3.0], [0.0, 0.0, 3.0]], atol=1e-12)
    np.testing.assert_allclose(dist, [0.5, 0.4], atol=1e-12)


def test_locate_project_surface_on_the_bent_pad(tmp_path):
    """On the pad bent 180 deg the N9 average of the taxels lies on a chord inside the
    cylinder; projected, the located points are on the outer surface."""
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    surface = pad_surface_stl(tmp_path / "pad.stl")
    states = pad_states(tmp_path / "s.npz", angles_deg=(0.0, 180.0))
    sc = scene(tmp_path, "state = 1\n")
    run_bench(sc, taxels, states, tmp_path / "b", surface_path=surface)
    frames = tmp_path / "b" / "small" / "frames.npz"
    r = 48 / np.pi

    def radius(folder):
        m = read_table(folder / "measured.csv", ["sample", "x_mm", "y_mm", "z_mm"])
        return np.hypot(m["x_mm"], m["z_mm"] - (1.5 - r))

    locate_scene(sc, frames, taxels, states, tmp_path / "plain")
    proj = scene(tmp_path, 'state = 1\n[detection]\nproject = "surface"\n')
    res = locate_scene(proj, frames, taxels, states, tmp_path / "proj", surface_path=surface)
    assert np.all(radius(tmp_path / "plain") < r + 1.5 - 0.3)  # inside the body
    # on its outer face (4 mm facets), not the inner one 3 mm below
    assert np.allclose(radius(tmp_path / "proj"), r + 1.5, atol=0.2)
    assert res["projected_to_surface"]["mean_mm"] > 0.3
    # read in chunks of 7 frames on 2 threads: the same touches, the same figures
    small = locate_scene(
        proj,
        frames,
        taxels,
        states,
        tmp_path / "proj7",
        surface_path=surface,
        chunk_frames=7,
        workers=2,
    )
    assert (tmp_path / "proj7" / "touches.csv").read_bytes() == (
        tmp_path / "proj" / "touches.csv"
    ).read_bytes()
    assert small["frames"] > 7 * 4
    for key in ("touches", "max_mm"):
        assert small["projected_to_surface"][key] == res["projected_to_surface"][key]
    assert small["projected_to_surface"]["mean_mm"] == pytest.approx(
        res["projected_to_surface"]["mean_mm"], rel=1e-12
    )
    with pytest.raises(FrameError, match="project = surface needs the body's surface"):
        locate_scene(proj, frames, taxels, states, tmp_path / "x")
    from fruitcli.errors import SceneError

    with pytest.raises(SceneError, match=r"\[detection\].project: expected one of none, surface"):
        scene(tmp_path, '[detection]\nproject = "nearest"\n')


def test_frame_counts_saturate_at_the_boards_16_bit_range():
    from fruitcli.sensing.skin.forward import frame_counts

    got = frame_counts(np.array([[-5.0, 10.0, 1e6]]), np.zeros(3), np.random.default_rng(0))
    assert got.tolist() == [[0, 10, 65535]]


def test_a_descent_over_the_threshold_at_its_start_starts_higher():
    """A strong wide touch crosses the threshold already 5 mm up: its descent starts at
    the next of START_GAPS_MM from which the first frame is under it, so the recording
    shows the approach; a weak one starts at 5 mm."""
    from fruitcli.sensing.skin.virtual_bench import START_GAPS_MM, descend

    taxels = forward.pad_taxels_mm(z_mm=3.0)
    rest = np.full(len(taxels), 500.0)
    contact = taxels[:2] + [4.0, 4.0, 0.0]
    runs = {}
    for name, counts in (("weak", 60.0), ("strong", 4000.0)):
        params = forward.SkinParams(forward.default_footprints_mm(), counts, 2.0, 0.0, 1.0)
        skin = forward.make_skin(len(taxels), 0, params)
        runs[name] = descend(
            contact, taxels, rest, skin, "small", 0.1, 10, 20.0, np.random.default_rng(0)
        )
    assert runs["weak"].start_gap_mm.tolist() == [START_GAPS_MM[0]] * 2
    strong = runs["strong"]
    # 4000 counts fall under 20 only past 5.3 mm of gap (2 mm decay): 10 mm is the start
    assert strong.start_gap_mm.tolist() == [START_GAPS_MM[1]] * 2
    last = np.flatnonzero(strong.sample >= 0)
    first = np.r_[10, last[:-1] + 1]  # each descent's first frame
    over = (strong.counts - strong.counts[:10].mean(axis=0) > 20.0).any(axis=1)
    assert not over[first].any() and over[last].all()
