"""Hovers: below the touch threshold, with hysteresis, keeping their session into a touch,
never counted as touches; and the bad inputs that refuse them."""

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import FrameError
from fruitcli.output_folder import MARKER
from fruitcli.sensing.detection.frames_to_touches import Locator, Stream
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.detection.touch_table import HOVER, TOUCH, TouchTable
from fruitcli.sensing.frames.board import default_board
from fruitcli.sensing.frames.recording import Recording, write_npz
from fruitcli.sensing.skin import forward
from fruitcli.sensing.skin.heights import GapLaw
from fruitcli.tables import Taxels

BASE = 500.0
LAW = GapLaw(60.0, 2.0, forward.default_footprints_mm()["small"], 1.0)  # noise std 1


def grid_taxels() -> Taxels:
    i, j = np.divmod(np.arange(21 * 12), 12)
    return Taxels(np.arange(i.size), i, j, np.stack([16.0 * i, 12.0 * j, 0.0 * i], axis=1))


def finger(taxels: Taxels, gap_mm: float, point=(84.0, 57.0, 0.0)) -> np.ndarray:
    """Mean taxel counts (T,) with the small indenter `gap_mm` above `point`."""
    dist = np.linalg.norm(taxels.xyz_mm - np.asarray(point), axis=1)
    return BASE + forward.activation_counts(dist[None, :], np.array([gap_mm]), "small")[0]


def stream(**settings) -> tuple[Stream, Taxels]:
    taxels = grid_taxels()
    s = Settings(hovers=True, track_gate_mm=20.0, **settings)
    loc = Locator(taxels, default_board(), taxels.xyz_mm, s, heights=LAW)
    return Stream(loc, np.full(len(taxels), BASE)), taxels


def runs(frames_with_rows: list[bool]) -> int:
    """How many separate runs of frames have rows."""
    x = np.r_[False, np.asarray(frames_with_rows), False].astype(int)
    return int((np.diff(x) == 1).sum())


def test_default_hover_levels_come_from_the_noise():
    st, _ = stream()
    assert st.loc.hover_levels == (8.0, 5.0)  # 8 and 8 - 3 noise std


def test_a_hand_held_at_the_hover_threshold_gives_one_hover_not_a_flicker():
    """The peak swings 1.5 counts either side of the hover threshold (8 counts): with the
    default hysteresis (3 counts) one hover; without, a new one on every swing up."""
    taxels = grid_taxels()
    peak0 = finger(taxels, 0.0).max() - BASE  # counts of the peak taxel at contact
    swing = 8.0 + 1.5 * np.sin(np.arange(200) / 3.0)
    counts = [BASE + (finger(taxels, 0.0) - BASE) * (p / peak0) for p in swing]
    for hysteresis, want in ((None, 1), (0.0, None)):
        st, _ = stream(hover_hysteresis_counts=hysteresis)
        tables = [st.step(c.copy(), None, f) for f, c in enumerate(counts)]
        rows = [len(t) > 0 for t in tables]
        assert all((t.kind == HOVER).all() for t in tables)
        if want is not None:
            assert runs(rows) == want
            assert len({int(t.touch[0]) for t in tables if len(t)}) == 1
        else:
            assert runs(rows) > 10  # the flicker the hysteresis removes


def test_a_hand_held_at_the_threshold_with_noise_stays_one_hover():
    """Gaussian noise of the law's std (1 count) on every taxel, 500 frames, the peak's
    mean exactly at the hover threshold: one hover (leaving needs a 3-std dip)."""
    taxels = grid_taxels()
    st, _ = stream()
    peak0 = finger(taxels, 0.0).max() - BASE
    mean = BASE + (finger(taxels, 0.0) - BASE) * (8.0 / peak0)
    rng = np.random.default_rng(3)
    tables = [st.step(mean + rng.normal(0, 1.0, mean.size), None, f) for f in range(500)]
    assert runs([len(t) > 0 for t in tables]) == 1
    assert len({int(t.touch[0]) for t in tables if len(t)}) == 1


def test_a_hover_coming_down_becomes_a_touch_with_the_same_session():
    taxels = grid_taxels()
    st, _ = stream()
    gaps = np.r_[np.linspace(5.0, 0.0, 51), np.zeros(5), np.linspace(0.0, 5.0, 51)]
    tables = [st.step(finger(taxels, g), None, f) for f, g in enumerate(gaps)]
    got = TouchTable.concat(tables)
    assert set(got.touch.tolist()) == {0}  # one session throughout
    kinds = got.kind.tolist()
    first_touch = kinds.index(TOUCH)
    assert kinds[:first_touch] and set(kinds[:first_touch]) == {HOVER}
    # the touch starts where the peak taxel (p0 counts at contact) crosses 20 counts:
    # gap 2 ln(p0 / 20); hovers start where it crosses 8 counts, 2 ln(p0 / 8)
    p0 = finger(taxels, 0.0).max() - BASE
    gap_at = gaps[got.frame]
    assert gap_at[first_touch] <= 2 * np.log(p0 / 20) < gap_at[first_touch - 1]
    assert gap_at[0] <= 2 * np.log(p0 / 8) < gap_at[0] + 0.1
    np.testing.assert_allclose(got.height_mm, gap_at, atol=1e-6)
    assert got.height_mm[got.kind == HOVER].min() > 2 * np.log(p0 / 20) - 1e-6
    # and back up: hovering again, still the same session
    assert kinds[-1] == HOVER


def test_hovers_leave_the_touches_as_they_were():
    """The same frames with and without hovers: the touch rows are identical."""
    taxels = grid_taxels()
    rng = np.random.default_rng(5)
    gaps = np.r_[np.linspace(4.0, -0.5, 40), np.linspace(-0.5, 4.0, 40)]
    counts = [
        finger(taxels, g, (60.0 + k, 40.0, 0.0)) + rng.normal(0, 1, 252) for k, g in enumerate(gaps)
    ]
    st, _ = stream()
    loc = Locator(taxels, default_board(), taxels.xyz_mm, Settings(track_gate_mm=20.0), heights=LAW)
    plain = Stream(loc, np.full(len(taxels), BASE))
    with_h = TouchTable.concat([st.step(c.copy(), None, f) for f, c in enumerate(counts)])
    without = TouchTable.concat([plain.step(c.copy(), None, f) for f, c in enumerate(counts)])
    assert (with_h.kind == HOVER).sum() > 5
    only = with_h.touches_only()
    for name in ("frame", "i", "j", "xyz_mm", "peak", "height_mm", "strength"):
        np.testing.assert_array_equal(getattr(only, name), getattr(without, name))


def test_hover_threshold_at_or_above_the_touch_threshold_is_refused():
    taxels = grid_taxels()
    for bad in (20.0, 25.0):
        with pytest.raises(
            FrameError,
            match=r"^\[detection\]\.hover_threshold_counts: "
            r"expected > 0 and below the touch threshold 20",
        ):
            Locator(
                taxels,
                default_board(),
                taxels.xyz_mm,
                Settings(hovers=True, hover_threshold_counts=bad),
                heights=LAW,
            )
    noisy = GapLaw(60.0, 2.0, 6.0, 3.0)  # 8 x 3 counts of noise: above 20
    with pytest.raises(FrameError, match="8 x the skin's noise std 3"):
        Locator(taxels, default_board(), taxels.xyz_mm, Settings(hovers=True), heights=noisy)


def taxel_csv(path):
    lines = ["id,i,j,x_mm,y_mm,z_mm"] + [
        f"{n},{n // 12},{n % 12},{16.0 * (n // 12)},{12.0 * (n % 12)},0.0" for n in range(252)
    ]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_cli_bad_hover_threshold_and_a_skin_without_gap_law(tmp_path):
    taxels = grid_taxels()
    frames = np.stack([np.full(252, BASE)] * 10 + [finger(taxels, g) for g in (3, 2, 1, 0)])
    write_npz(
        tmp_path / "f.npz",
        Recording(
            np.round(frames).astype(np.int64).reshape(-1, 21, 12),
            np.arange(14) / 60.0,
            meta={"board": "muca"},
        ),
    )
    taxel_csv(tmp_path / "t.csv")
    (tmp_path / "s.toml").write_text("[detection]\nhovers = true\nhover_threshold_counts = 20\n")
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / MARKER).write_text("{}\n")  # the folder of an earlier run
    (tmp_path / "o" / "touches.csv").write_text("kept\n")
    r = CliRunner().invoke(
        cli,
        [
            "locate",
            str(tmp_path / "f.npz"),
            "--taxels",
            str(tmp_path / "t.csv"),
            "--scene",
            str(tmp_path / "s.toml"),
            "--out",
            str(tmp_path / "o"),
        ],
    )
    assert r.exit_code != 0
    assert (
        r.output.strip()
        .splitlines()[-1]
        .endswith(
            "[detection].hover_threshold_counts: expected > 0 and below the touch threshold 20 "
            "counts, got 20"
        )
    )
    assert "Traceback" not in r.output
    assert (tmp_path / "o" / "touches.csv").read_text() == "kept\n"
    (tmp_path / "skin.toml").write_text(
        "[skin]\nfootprint_sigma_mm = { small = 6.0 }\ncontact_counts = 55.0\n"
    )
    r = CliRunner().invoke(
        cli,
        [
            "locate",
            str(tmp_path / "f.npz"),
            "--taxels",
            str(tmp_path / "t.csv"),
            "--skin",
            str(tmp_path / "skin.toml"),
            "--out",
            str(tmp_path / "o"),
        ],
    )
    assert r.exit_code != 0
    assert "skin.toml: [skin].gap_decay_mm: missing; heights need the skin's gap law" in r.output
    assert len(r.output.strip().splitlines()) == 1
    assert (tmp_path / "o" / "touches.csv").read_text() == "kept\n"


def test_cli_locate_with_a_skin_gives_its_heights(tmp_path):
    taxels = grid_taxels()
    gaps = [3.0, 2.0, 1.0, 0.5]
    frames = np.stack([np.full(252, BASE)] * 10 + [finger(taxels, g) for g in gaps])
    write_npz(
        tmp_path / "f.npz",
        Recording(
            np.round(frames).reshape(-1, 21, 12).astype(int),
            np.arange(14) / 60.0,
            meta={"board": "muca"},
        ),
    )
    taxel_csv(tmp_path / "t.csv")
    # the same skin, its gap law stated; counts rounded: heights within 0.15 mm
    (tmp_path / "skin.toml").write_text(
        "[skin]\nfootprint_sigma_mm = {{ small = {!r} }}\ncontact_counts = 60.0\n"
        "gap_decay_mm = 2.0\nnoise_std_counts = 1.0\n".format(
            forward.default_footprints_mm()["small"]
        )
    )
    r = CliRunner().invoke(
        cli,
        [
            "locate",
            str(tmp_path / "f.npz"),
            "--taxels",
            str(tmp_path / "t.csv"),
            "--skin",
            str(tmp_path / "skin.toml"),
            "--threshold",
            "5",
            "--out",
            str(tmp_path / "o"),
        ],
    )
    assert r.exit_code == 0, r.output
    rows = [
        ln.split(",")
        for ln in (tmp_path / "o" / "touches.csv").read_text().splitlines()
        if not ln.startswith("#")
    ]
    head, body = rows[0], rows[1:]
    h = [float(r[head.index("height_mm")]) for r in body]
    assert [int(r[0]) for r in body] == [10, 11, 12, 13]
    np.testing.assert_allclose(h, gaps, atol=0.15)
    assert {r[head.index("kind")] for r in body} == {"touch"}


def test_json_lines_carry_heights_strengths_sizes_and_kinds():
    import json

    from fruitcli.sensing.live.loop import LiveLocator

    taxels = grid_taxels()
    loc = Locator(
        taxels,
        default_board(),
        taxels.xyz_mm,
        Settings(hovers=True, baseline_frames=2),
        heights=LAW,
    )
    live = LiveLocator(loc)
    lines = [
        live.push(np.round(finger(taxels, g)).reshape(21, 12).astype(np.int64), k / 60)
        for k, g in enumerate([20.0, 20.0, 3.0, 0.5])
    ]
    hover, touch = (json.loads(x)["touches"][0] for x in lines[2:])
    assert (hover["kind"], touch["kind"]) == ("hover", "touch")
    assert hover["touch"] == touch["touch"]
    assert hover["height_mm"] == pytest.approx(3.0, abs=0.2)
    assert touch["height_mm"] == pytest.approx(0.5, abs=0.1)
    assert touch["strength"] == pytest.approx(np.exp(-0.25), abs=0.02)
    assert hover["size_mm"] is None or hover["size_mm"] > 0
    assert set(touch) >= {"height_err_mm", "size_mm"}


def test_cli_locate_with_a_scene_gives_heights_from_the_scenes_skin(tmp_path):
    """The fingers come down on the default skin (gap decay 2 mm); a scene whose [skin]
    states a gap decay of 4 mm reads every strength as twice the height."""
    taxels = grid_taxels()
    gaps = [1.5, 1.0, 0.5]
    frames = np.stack([np.full(252, BASE)] * 10 + [finger(taxels, g) for g in gaps])
    write_npz(
        tmp_path / "f.npz",
        Recording(np.round(frames).reshape(-1, 21, 12).astype(int), np.arange(13) / 60.0),
    )
    taxel_csv(tmp_path / "t.csv")
    (tmp_path / "s.toml").write_text(
        "[skin]\ngap_decay_mm = 4.0\n[detection]\nthreshold_counts = 5\n"
    )
    args = ["locate", str(tmp_path / "f.npz"), "--taxels", str(tmp_path / "t.csv")]
    r = CliRunner().invoke(
        cli, [*args, "--scene", str(tmp_path / "s.toml"), "--out", str(tmp_path / "o")]
    )
    assert r.exit_code == 0, r.output
    rows = [
        ln.split(",")
        for ln in (tmp_path / "o" / "touches.csv").read_text().splitlines()
        if not ln.startswith("#")
    ]
    head, body = rows[0], rows[1:]
    assert [int(b[0]) for b in body] == [10, 11, 12]
    h = [float(b[head.index("height_mm")]) for b in body]
    np.testing.assert_allclose(h, 2 * np.array(gaps), atol=0.3)


def test_cli_live_with_a_skin_gives_its_heights(tmp_path):
    """`fruit live --skin` over a pseudo-terminal: the heights of a finger coming down
    are the gaps it was built at, as `fruit locate --skin` gives them."""
    import json

    from fruitcli.sensing.live.board_emulator import BoardEmulator

    taxels = grid_taxels()
    gaps = [3.0, 2.0, 1.0, 0.5]
    frames = np.stack([np.full(252, BASE)] * 10 + [finger(taxels, g) for g in gaps])
    frames = np.round(frames).reshape(-1, 21, 12).astype(np.int64)
    frames = np.concatenate([frames, frames[:1]])  # the finger lifts: the last line is read
    taxel_csv(tmp_path / "t.csv")
    (tmp_path / "s.toml").write_text('[scene]\nname = "live-heights"\n')
    (tmp_path / "skin.toml").write_text(
        "[skin]\nfootprint_sigma_mm = {{ small = {!r} }}\ncontact_counts = 60.0\n"
        "gap_decay_mm = 2.0\nnoise_std_counts = 1.0\n".format(
            forward.default_footprints_mm()["small"]
        )
    )
    em = BoardEmulator(frames, fps=0, wait_for_reader=True)
    th = em.start()
    r = CliRunner().invoke(
        cli,
        [
            "live",
            str(tmp_path / "s.toml"),
            "--port",
            em.path,
            "--taxels",
            str(tmp_path / "t.csv"),
            "--skin",
            str(tmp_path / "skin.toml"),
            "--threshold",
            "5",
            "--frames",
            str(len(frames)),
        ],
    )
    em.stop.set()
    th.join(5)
    assert r.exit_code == 0, r.output
    lines = [json.loads(ln) for ln in r.output.splitlines() if ln.startswith("{")]
    touched = [ln for ln in lines if ln["touches"]]
    assert [ln["frame"] for ln in touched] == [10, 11, 12, 13]
    heights = [ln["touches"][0]["height_mm"] for ln in touched]
    np.testing.assert_allclose(heights, gaps, atol=0.15)
    assert {ln["touches"][0]["kind"] for ln in touched} == {"touch"}
    assert len({ln["touches"][0]["touch"] for ln in touched}) == 1  # one session
