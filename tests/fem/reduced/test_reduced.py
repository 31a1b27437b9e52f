"""The reduced model: response surfaces (closed forms, an exact linear case), its error
at held-out pressures on a small two-chamber pad against fresh full solves, the
pressure CSV, `fruit simulate --pressures` with both models and its bad inputs, and
the planner rebuilding it when the pressure range changes."""

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import FruitError, SolverError
from fruitcli.fem.pressure_table import read_pressures, write_pressures
from fruitcli.fem.reduced import model as reduced_mod
from fruitcli.fem.reduced import response_surface as rs
from fruitcli.fem.reduced.build import (
    PressureBoxInputs,
    pressure_box,
    pressure_range,
    reduce_inputs,
)
from fruitcli.scene import parse_scene
from fruitcli.tables import read_taxels
from fruitcli.workflow import planner

PAD = """
[scene]
name = "reduced-pad"
[geometry]
pad_size_mm = [80.0, 60.0, 10.0]
[[geometry.chamber]]
name = "left"
ellipsoid = {center_mm = [-18.0, 0.0, 4.0], radii_mm = [14.0, 14.0, 2.5]}
[[geometry.chamber]]
name = "right"
ellipsoid = {center_mm = [18.0, 0.0, 4.0], radii_mm = [14.0, 14.0, 2.5]}
[grid]
count = [4, 3]
spacing_x_mm = 16.0
spacing_y_mm = 16.0
[fem]
element = "p1"
[material]
model = "corotational"
[mesh]
size_mm = 6.0
[[fixed]]
box_mm = [-50, -50, -0.01, 50, 50, 0.01]
[actuation]
pressure_kpa = {left = [0.0, 3.0, 0.0], right = [0.0, 0.0, 3.0]}
[reduced]
validation = 20
"""


def test_legendre_basis_closed_forms_and_exponents():
    xi = np.array([-1.0, -0.3, 0.0, 0.7, 1.0])
    t = rs.legendre_table(xi, 3)
    assert np.allclose(t[2], (3 * xi**2 - 1) / 2, atol=1e-15)
    assert np.allclose(t[3], (5 * xi**3 - 3 * xi) / 2, atol=1e-15)
    e = rs.exponents(3, 2)
    assert len(e) == 10 and e[0].tolist() == [0, 0, 0] and e.sum(axis=1).max() == 2
    phi = rs.basis(np.array([[0.5, -0.2, 0.1]]), e)[0]
    row = {tuple(r): v for r, v in zip(e.tolist(), phi, strict=True)}
    assert row[(1, 1, 0)] == pytest.approx(0.5 * -0.2)
    assert row[(0, 0, 2)] == pytest.approx((3 * 0.01 - 1) / 2)
    assert np.allclose(rs.basis(np.array([0.5, -0.2, 0.1]), e), phi)  # one vector
    g = rs.snake_grid(3, 4)
    assert len(g) == 64 and len(np.unique(g, axis=0)) == 64
    assert np.all(np.abs(np.diff(g, axis=0)).sum(axis=1) == 1)  # one grid step each
    assert np.allclose(rs.lobatto_points(3), [-1, 0, 1])


def test_degree_one_fit_of_a_linear_map_is_exact():
    """A linear map of the pressures is reproduced to 1e-9 at any pressures of the box
    by the degree-1 fit, and its leave-one-out residuals vanish."""
    rng = np.random.default_rng(1)
    lo, hi = np.array([-1.0, 0.0, 2.0]), np.array([4.0, 12.0, 3.0])
    a, b = rng.normal(size=(3, 7)), rng.normal(size=7)
    grid = rs.lobatto_points(3)[rs.snake_grid(3, 3)]
    p = lo + (grid + 1) / 2 * (hi - lo)
    e = rs.exponents(3, 1)
    coef = rs.fit(rs.basis(grid, e), p @ a + b)
    test = lo + rng.random((50, 3)) * (hi - lo)
    got = rs.basis(rs.scale(test, lo, hi), e) @ coef
    assert np.abs(got - (test @ a + b)).max() < 1e-9
    assert np.abs(rs.leave_one_out(rs.basis(grid, e), p @ a + b)).max() < 1e-9


def test_pressure_box_from_actuation_margin_and_range():
    sc = parse_scene(PAD, Path("/tmp/pad.toml"), must_exist=False)
    lo, hi = pressure_box(sc, ["left", "right"])
    assert np.allclose(lo, [-0.3, -0.3]) and np.allclose(hi, [3.3, 3.3])
    sc = parse_scene(
        PAD + "pressure_range_kpa = [1.0, 5.0]\n", Path("/tmp/pad.toml"), must_exist=False
    )
    assert pressure_box(sc, ["left", "right"])[1].tolist() == [5.0, 5.0]
    with pytest.raises(FruitError, match=r"\[reduced\].pressure_range_kpa: expected \[lo, hi\]"):
        parse_scene(
            PAD + "pressure_range_kpa = [5.0, 1.0]\n", Path("/tmp/pad.toml"), must_exist=False
        )


def test_pressure_range_from_its_inputs_alone():
    """The box from typed inputs, no scene: the range for every chamber; else each
    chamber's pressures widened by the margin of its span, a chamber held at one
    pressure by the largest span; one line when nothing spans or volumes are controlled."""
    box = PressureBoxInputs(None, 0.5, {"a": (0.0, 2.0), "b": (1.0, 1.0)}, False)
    lo, hi = pressure_range(box, ["a", "b", "c"])  # c: no pressures, held at 0 kPa
    assert lo.tolist() == [-1.0, 0.0, -1.0] and hi.tolist() == [3.0, 2.0, 1.0]
    lo, hi = pressure_range(PressureBoxInputs((-2.0, 4.0), 0.5, {}, True), ["a", "b"])
    assert lo.tolist() == [-2.0, -2.0] and hi.tolist() == [4.0, 4.0]
    with pytest.raises(FruitError, match=r"^\[actuation\].volume_growth_mm3: the reduced"):
        pressure_range(PressureBoxInputs(None, 0.1, {"a": (0.0, 2.0)}, True), ["a"])
    with pytest.raises(FruitError, match=r"^\[reduced\]: no pressure range"):
        pressure_range(PressureBoxInputs(None, 0.1, {}, False), ["a"])
    with pytest.raises(FruitError, match=r"every chamber at one pressure"):
        pressure_range(PressureBoxInputs(None, 0.1, {"a": (2.0,)}, False), ["a"])


def test_reduce_inputs_read_the_scene_once():
    """The reduce stage's inputs hold the scene's [reduced] settings and its box."""
    sc = parse_scene(PAD, Path("/tmp/pad.toml"), must_exist=False)
    inputs = reduce_inputs(sc)
    assert (inputs.points_per_axis, inputs.max_degree, inputs.validation, inputs.seed) == (
        sc.reduced.points_per_axis,
        sc.reduced.max_degree,
        sc.reduced.validation,
        sc.reduced.seed,
    )
    lo, hi = pressure_range(inputs.box, ["left", "right"])
    assert np.array_equal(lo, pressure_box(sc, ["left", "right"])[0])
    assert np.array_equal(hi, pressure_box(sc, ["left", "right"])[1])


def test_pressure_csv_round_trip(tmp_path):
    kpa = np.array([[0.1, 2.0 / 3.0], [1e-7, 12.5], [-0.3, 3.3]])
    write_pressures(tmp_path / "p.csv", ["left", "right"], kpa)
    text = (tmp_path / "p.csv").read_text()
    assert text.startswith("# ") and "left_kpa,right_kpa" in text
    got, lines = read_pressures(tmp_path / "p.csv", ["left", "right"])
    assert np.array_equal(got, kpa) and lines.tolist() == [3, 4, 5]
    swapped, _ = read_pressures(tmp_path / "p.csv", ["right", "left"])  # by name, not place
    assert np.array_equal(swapped, kpa[:, ::-1])


@pytest.mark.parametrize(
    "text, message",
    [
        ("left_kpa\n1.0\n", "missing column(s) right_kpa"),
        ("left_kpa,right_kpa,c3_kpa\n1,2,3\n", "unexpected column(s) c3_kpa"),
        ("left_kpa,right_kpa\n1.0,nan\n", "row 2: column right_kpa: not finite"),
        ("left_kpa,right_kpa\n1.0,x\n", "row 2: column right_kpa: not a number"),
        ("# only a comment\n", "empty file"),
        ("left_kpa,right_kpa\n", "no data rows"),
        ("left_kpa,right_kpa\n1.0\n", "row 2: expected 2 fields, got 1"),
    ],
)
def test_pressure_csv_bad_inputs(tmp_path, text, message):
    (tmp_path / "p.csv").write_text(text)
    with pytest.raises(FruitError, match=message.replace("(", r"\(").replace(")", r"\)")):
        read_pressures(tmp_path / "p.csv", ["left", "right"])


@pytest.fixture(scope="module")
def pad_run(tmp_path_factory):
    """The pad's reduced model built by `fruit run --until reduce`, and fresh full and
    reduced `fruit simulate --pressures` at pressures it was not built on."""
    root = tmp_path_factory.mktemp("pad")
    (root / "pad.toml").write_text(PAD)
    out = root / "out"
    res = CliRunner().invoke(
        cli, ["run", str(root / "pad.toml"), "--out", str(out), "--until", "reduce"]
    )
    assert res.exit_code == 0, res.output
    rng = np.random.default_rng(7)
    kpa = -0.3 + rng.random((4, 2)) * 3.6
    write_pressures(root / "p.csv", ["left", "right"], kpa)
    taxels = out / "pad-grid" / "taxels.csv"
    states = {}
    for kind in ("reduced", "full"):
        res = CliRunner().invoke(
            cli,
            [
                "simulate",
                str(root / "pad.toml"),
                "--out",
                str(root / kind),
                "--pressures",
                str(root / "p.csv"),
                "--model",
                kind,
                "--taxels",
                str(taxels),
            ],
        )
        assert res.exit_code == 0, res.output
        with np.load(root / kind / "states.npz") as st:
            states[kind] = {k: st[k] for k in st.files}
    return root, out, kpa, states


def test_reduced_model_within_its_bound_at_held_out_pressures(pad_run):
    """The stored validation (20 held-out vectors) is within 0.05 mm and 1 %, and
    fresh full solves at 4 more pressures agree with the reduced states.npz to the same
    bounds: taxels, chamber volumes and every node."""
    root, out, kpa, states = pad_run
    model = reduced_mod.load(out / "reduce" / "reduced.npz")
    v = model.validation()
    assert v["vectors"] == 20 and v["within_bound"] and v["full_solves"] == 25 + 20
    assert v["taxel_max_mm"] < reduced_mod.TAXEL_BOUND_MM
    assert "WARNING" not in model.describe()
    red, full = states["reduced"], states["full"]
    assert str(red["model"]) == "reduced" and str(full["model"]) == "full"
    assert np.allclose(red["pressure_kpa"], kpa) and np.allclose(full["pressure_kpa"], kpa)
    moved = np.abs(full["taxels_mm"] - model.taxels(np.zeros(2))).max()
    assert moved > 0.1  # the pressures move the taxels well past the bound
    err = np.linalg.norm(red["taxels_mm"] - full["taxels_mm"], axis=2)
    assert err.max() < reduced_mod.TAXEL_BOUND_MM
    vol = np.abs(red["chamber_volume_mm3"] / full["chamber_volume_mm3"] - 1)
    assert vol.max() < reduced_mod.VOLUME_BOUND_PCT / 100
    assert np.abs(red["displacement_mm"] - full["displacement_mm"]).max() < 0.05
    assert set(full) - {"reduced_degree"} <= set(red)  # the usual states.npz keys


def test_simulate_pressures_outside_the_range(pad_run):
    """Outside the reduced model's range: one line naming the row for `reduced`, solved
    for `full`."""
    root, out, _, _ = pad_run
    (root / "far.csv").write_text("# kPa\nleft_kpa,right_kpa\n1.0,1.0\n1.0,4.5\n")
    args = [
        "simulate",
        str(root / "pad.toml"),
        "--out",
        str(root / "far"),
        "--pressures",
        str(root / "far.csv"),
        "--taxels",
        str(out / "pad-grid" / "taxels.csv"),
    ]
    res = CliRunner().invoke(cli, args + ["--model", "reduced"])
    assert res.exit_code == 1
    last = res.output.strip().splitlines()[-1]
    assert "far.csv: row 4: pressures [1.0, 4.5] kPa outside the reduced model's range" in last
    assert "use --model full" in last and "Traceback" not in res.output
    assert not (root / "far" / "states.npz").exists()
    res = CliRunner().invoke(cli, args + ["--model", "full"])
    assert res.exit_code == 0, res.output
    with np.load(root / "far" / "states.npz") as st:
        assert st["pressure_kpa"].tolist() == [[1.0, 1.0], [1.0, 4.5]]


def test_simulate_pressures_bad_csv_is_one_line(pad_run, tmp_path):
    root, _, _, _ = pad_run
    (tmp_path / "bad.csv").write_text("left_kpa,middle_kpa\n1.0,2.0\n")
    for kind in ("full", "reduced"):
        res = CliRunner().invoke(
            cli,
            [
                "simulate",
                str(root / "pad.toml"),
                "--out",
                str(tmp_path / kind),
                "--pressures",
                str(tmp_path / "bad.csv"),
                "--model",
                kind,
            ],
        )
        assert res.exit_code == 1
        assert res.output.strip().splitlines() == [
            f"Error: {tmp_path / 'bad.csv'}: row 1: missing column(s) right_kpa (found "
            "left_kpa, middle_kpa)"
        ]


def test_check_range_names_the_row():
    arrays = {"range_lo_kpa": np.array([0.0, 0.0]), "range_hi_kpa": np.array([2.0, 3.0])}
    m = reduced_mod.ReducedModel(
        ["a", "b"],
        arrays["range_lo_kpa"],
        arrays["range_hi_kpa"],
        rs.exponents(2, 1),
        np.zeros((3, 3)),
        np.zeros((3, 2)),
        np.zeros((3, 1)),
        np.zeros((1, 3)),
        np.zeros((1, 3)),
        arrays,
    )
    m.check_range(np.array([[0.0, 3.0], [2.0, 0.0]]))
    with pytest.raises(SolverError, match=r"p.csv: row 12: pressures \[2.5, 1.0\] kPa outside"):
        m.check_range(np.array([[0.0, 3.0], [2.5, 1.0]]), "p.csv", rows=[11, 12])


def test_planner_rebuilds_the_reduced_model_when_its_range_changes(pad_run, tmp_path):
    """Reused while unchanged (and when only the states inside the same range change),
    rebuilt when [reduced].pressure_range_kpa or the material changes."""
    root, out, _, _ = pad_run

    def action(text):
        path = root / "variant.toml"
        path.write_text(text)
        sc = parse_scene(text, path)
        return {s.stage: s.action for s in planner.plan(sc, out, until="reduce")}["reduce"]

    assert action(PAD) == "reuse"
    assert action(PAD.replace("right = [0.0, 0.0, 3.0]", "right = [0.0, 3.0, 0.0]")) == "reuse"
    assert action(PAD + "pressure_range_kpa = [0.0, 4.0]\n") == "run"
    assert action(PAD.replace("right = [0.0, 0.0, 3.0]", "right = [0.0, 0.0, 4.0]")) == "run"
    assert (
        action(
            PAD.replace(
                'model = "corotational"', 'model = "corotational"\nyoung_modulus_kpa = 150.0'
            )
        )
        == "run"
    )


def test_fruit_run_locates_a_recording_with_pressures_on_the_reduced_model(pad_run, tmp_path):
    """`fruit run` on a scene whose [frames].recording carries chamber pressures: the
    locate stage takes each frame's taxels from the scene's reduced model (touches.csv
    equals run_locate's with that model, byte for byte); [frames].model = "full" takes
    them along the simulated states; without [reduced] the reduce stage is then needed."""
    from fruitcli.sensing.frames.recording import Recording, write_npz
    from tests.helpers.locate import locate_scene
    from tests.sensing.detection.test_locate_chunks import touch_frames

    root, out, _, _ = pad_run
    rng = np.random.default_rng(5)
    n = 200
    kpa = rng.uniform(0.0, 3.0, (n, 2))
    write_npz(
        root / "rec.npz",
        Recording(touch_frames(n, rng), np.arange(n) / 30.0, kpa, ("left", "right")),
    )
    text = PAD + '[frames]\nrecording = "rec.npz"\n'
    got = {}
    for kind, scene_text in (
        ("reduced", text),
        ("full", text.replace('"rec.npz"\n', '"rec.npz"\nmodel = "full"\n')),
    ):
        (root / "rec.toml").write_text(scene_text)
        res = CliRunner().invoke(cli, ["run", str(root / "rec.toml"), "--out", str(out)])
        assert res.exit_code == 0, res.output
        got[kind] = (out / "locate" / "recording" / "touches.csv").read_bytes()
    sc = parse_scene(text, root / "rec.toml")
    taxels, states = out / "pad-grid" / "taxels.csv", out / "simulate" / "states.npz"
    model = reduced_mod.load(out / "reduce" / "reduced.npz")
    for kind, reduced in (("reduced", model), ("full", None)):
        res = locate_scene(sc, root / "rec.npz", taxels, states, tmp_path / kind, reduced=reduced)
        assert res["model"] == kind and res["touches"] > 20
        assert (tmp_path / kind / "touches.csv").read_bytes() == got[kind]
    assert got["reduced"] != got["full"]  # the pressures move the taxels
    bare = text.replace("[reduced]\nvalidation = 20\n", "")
    (root / "bare.toml").write_text(bare)
    steps = {s.stage: s for s in planner.plan(parse_scene(bare, root / "bare.toml"), out)}
    assert steps["reduce"].action == "run" and "carries chamber pressures" in steps["reduce"].reason


def test_one_vector_basis_equals_the_batch_basis():
    """The live loop's one-vector path (Python floats) gives the batch basis."""
    lo, hi = np.array([-1.2, 0.0, 3.0]), np.array([13.2, 5.0, 4.0])
    e = rs.exponents(3, 4)
    rng = np.random.default_rng(2)
    m = reduced_mod.ReducedModel(
        ["a", "b", "c"],
        lo,
        hi,
        e,
        rng.normal(size=(len(e), 6)),
        np.zeros((len(e), 3)),
        np.zeros((len(e), 1)),
        np.zeros((1, 3)),
        np.zeros((1, 3)),
        {},
    )
    p = lo + rng.random((20, 3)) * (hi - lo)
    batch = m.taxels(p)
    assert batch.shape == (20, 2, 3)
    for row, want in zip(p, batch, strict=True):
        assert np.abs(m.taxels(row) - want).max() < 1e-12


def translating_model(lo, hi, shift_per_kpa, rest_xyz):
    """A degree-1 ReducedModel moving every taxel from rest_xyz (T, 3) by
    shift_per_kpa (3, K) @ p (mm): fitted to that exactly linear map, so exact to
    round-off."""
    k = len(lo)
    e = rs.exponents(k, 1)
    grid = rs.lobatto_points(2)[rs.snake_grid(k, 2)]
    p = lo + (grid + 1) / 2 * (hi - lo)
    y = rest_xyz.ravel() + np.tile(p @ shift_per_kpa.T, len(rest_xyz))  # (n, 3T)
    coef = rs.fit(rs.basis(grid, e), y)
    return reduced_mod.ReducedModel(
        ["left", "right"],
        lo,
        hi,
        e,
        coef,
        np.zeros((k + 1, k)),
        np.zeros((k + 1, 1)),
        np.zeros((1, 3)),
        np.zeros((1, 3)),
        {
            "validation_taxel_error_mm": np.zeros((1, 1)),
            "validation_volume_error_pct": np.zeros((1, k)),
            "validation_surface_error_mm": np.zeros((1, 1)),
            "sample_kpa": p,
            "build_s": np.array(0.0),
            "full_solves": np.array(len(p)),
        },
    )


@pytest.mark.parametrize(
    "detection", [{}, {"hysteresis_counts": 6.0, "drift_rate": 0.05, "track_gate_mm": 30.0}]
)
def test_locate_takes_each_frames_taxels_from_the_reduced_model(tmp_path, detection):
    """With a reduced model, a recording's frames with pressures put their touches at
    the taxels the model gives at those pressures (batch and stateful paths, chunked):
    a model that translates every taxel by B p moves each touch by B p of its frame from
    where it is located on the rest taxels plus the same translation at 0 kPa."""
    import csv

    from fruitcli.sensing.frames.recording import Recording, write_npz
    from tests.helpers.locate import locate_scene
    from tests.sensing.detection.test_locate_chunks import (
        full_grid,
        located,
        scene,
        touch_frames,
        write_taxels,
    )

    rng = np.random.default_rng(4)
    frames = touch_frames(300, rng, noisy_base=True)
    t_s = np.arange(300) / 30.0
    kpa = np.column_stack([rng.uniform(-2, 11, 300), rng.uniform(-1, 7, 300)])
    write_npz(tmp_path / "f.npz", Recording(frames, t_s, kpa[:, ::-1], ("right", "left")))
    taxels = write_taxels(tmp_path / "t.csv", full_grid())
    b = np.array([[0.3, -0.1], [0.0, 0.2], [1.0, 0.5]])
    model = translating_model(
        np.array([-3.0, -3.0]), np.array([12.0, 12.0]), b, read_taxels(taxels).xyz_mm
    )
    sc = scene(detection=detection)
    # on the rest taxels: the same recording without its pressures
    write_npz(tmp_path / "r.npz", Recording(frames, t_s))
    _, res0 = located(tmp_path, sc, tmp_path / "r.npz", taxels, out="rest")
    res = locate_scene(
        sc, tmp_path / "f.npz", taxels, None, tmp_path / "red", chunk_frames=64, reduced=model
    )
    assert res0["touches"] > 50 and res["model"] == "reduced"
    assert res["frames_outside_reduced_range"] == 0

    def rows(path):
        with open(path) as fh:
            return [r for r in csv.DictReader(line for line in fh if not line.startswith("#"))]

    rest, red = rows(tmp_path / "rest" / "touches.csv"), rows(tmp_path / "red" / "touches.csv")
    assert [(r["frame"], r["i"], r["j"]) for r in red] == [
        (r["frame"], r["i"], r["j"]) for r in rest
    ]
    for r0, r1 in zip(rest, red, strict=True):
        shift = b @ kpa[int(r0["frame"])]
        got = np.array([float(r1[c]) for c in ("x_mm", "y_mm", "z_mm")])
        want = np.array([float(r0[c]) for c in ("x_mm", "y_mm", "z_mm")]) + shift
        assert np.abs(got - want).max() < 2e-6


def test_reduced_online_clamps_to_the_range_and_skips_repeats():
    """The live loop's ReducedOnline: taxels at the pressures, a repeat not evaluated
    again, pressures outside the range evaluated at the nearest inside and counted."""
    from fruitcli.fem.online import ReducedOnline

    rest = np.array([[0.0, 0.0, 10.0], [16.0, 0.0, 10.0]])
    b = np.array([[0.3, -0.1], [0.0, 0.2], [1.0, 0.5]])
    live = ReducedOnline(translating_model(np.array([0.0, 0.0]), np.array([5.0, 5.0]), b, rest))
    assert np.allclose(live.taxels_mm, rest)
    assert live.update(np.array([1.0, 2.0])) and not live.update([1.0, 2.0])
    assert np.abs(live.taxels_mm - (rest + b @ [1.0, 2.0])).max() < 1e-12
    assert live.update([9.0, -1.0]) and live.clamped == 1
    assert np.abs(live.taxels_mm - (rest + b @ [5.0, 0.0])).max() < 1e-12
    assert "2 pressure vectors" in live.summary() and "1 outside its range" in live.summary()
    with pytest.raises(SolverError, match="expected 2 chamber pressures"):
        live.update([1.0])
