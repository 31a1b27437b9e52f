"""Heights from the electrostatic skin's crossing table: on a table that is the Gaussian
gap law sampled, the same heights as the gap law; fruit locate on an electrostatic scene
takes them from the skin stage's table."""

import json

import numpy as np
import pytest

from fruitcli.scene import default_scene
from fruitcli.sensing.detection.frames_to_touches import Locator
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.frames.board import default_board
from fruitcli.sensing.frames.recording import Recording, write_npz
from fruitcli.sensing.skin.crossing_heights import CrossingHeights
from fruitcli.sensing.skin.crossing_skin import CrossingSkin
from fruitcli.sensing.skin.heights import GapLaw
from fruitcli.tables import Taxels
from tests.helpers.locate import locate_scene

A, SIGMA, DECAY = 60.0, 6.2, 2.0  # counts, mm, mm


def gaussian_arrays():
    """crossing.npz's arrays and summary.json's dict of a table that samples
    A exp(-r^2 / 2 sigma^2) exp(-gap / decay) (counts_per_ff 1: dC = -counts)."""
    gap = np.linspace(0.0, 3.0, 13)
    dx = np.linspace(-8.0, 8.0, 65)
    g, x, y = np.meshgrid(gap, dx, dx, indexing="ij")
    drop = A * np.exp(-(x**2 + y**2) / (2 * SIGMA**2)) * np.exp(-g / DECAY)
    arrays = {
        "c0_ff": np.array(1000.0),
        "objects": np.array(["small"]),
        "gap_mm": gap,
        "dc_ff": -drop[None],
        "dx_mm": dx,
        "dy_mm": dx,
        "strain": np.array([0.0, 0.1]),
        "curvature_per_mm": np.array([0.0, 0.01]),
        "c_stretch_ff": np.full((2, 2), 1000.0),
        "c_bend_ff": np.full((2, 2), 1000.0),
    }
    summary = {
        "counts_per_ff": 1.0,
        "objects": {"small": {"footprint_sigma_mm": SIGMA, "gap_decay_mm": DECAY}},
    }
    return arrays, summary


def model():
    return CrossingHeights.of(CrossingSkin.from_table(*gaussian_arrays()), "small", 1.0)


def test_heights_invert_the_tables_fall_with_the_gap_inside_and_beyond_it():
    m = model()
    gaps = np.array([0.0, 0.25, 0.5, 1.0, 2.0, 2.9, 3.5, 5.0])  # the table ends at 3 mm
    s = np.exp(-gaps / DECAY)
    h, err = m.height_mm(s, np.full(gaps.size, 0.01))
    np.testing.assert_allclose(h, gaps, atol=0.01)
    # dg/ds = decay / s, up to the slope of the table linear between its 0.25 mm gaps
    np.testing.assert_allclose(err, DECAY * 0.01 / s, rtol=0.07)
    assert m.height_mm(np.array([1.3]), np.array([0.01]))[0][0] == 0.0  # a firm press
    assert m.sigma_mm == SIGMA and m.tail_decay_mm == pytest.approx(DECAY, rel=1e-9)


def test_touch_shapes_through_the_table_equal_the_gap_laws():
    i, j = np.divmod(np.arange(252), 12)
    taxels = Taxels(np.arange(252), i, j, np.stack([16.0 * i, 12.0 * j, 0.0 * i], axis=1))
    law = GapLaw(A, DECAY, SIGMA, 1.0)
    rng = np.random.default_rng(2)
    frames, truth = [], []
    for _ in range(30):
        p = np.array([rng.uniform(40, 280), rng.uniform(30, 100), 0.0])
        g = rng.uniform(0.0, 2.5)
        d = np.linalg.norm(taxels.xyz_mm - p, axis=1)
        frames.append(500.0 + A * np.exp(-0.5 * (d / SIGMA) ** 2) * np.exp(-g / DECAY))
        truth.append(g)
    frames = np.stack(frames).reshape(-1, 21, 12)
    got = {}
    for name, heights in (("table", model()), ("law", law)):
        loc = Locator(
            taxels, default_board(), taxels.xyz_mm, Settings(threshold_counts=5.0), heights=heights
        )
        got[name] = loc.batch(frames, np.full(252, 500.0))
    assert len(got["table"]) == 30 and np.array_equal(got["table"].frame, np.arange(30))
    np.testing.assert_allclose(got["table"].height_mm, truth, atol=0.05)
    np.testing.assert_allclose(got["table"].height_mm, got["law"].height_mm, atol=0.05)
    np.testing.assert_allclose(got["table"].strength, got["law"].strength, rtol=0.02)


def test_locate_on_an_electrostatic_scene_takes_heights_from_the_skin_stages_table(tmp_path):
    arrays, summary = gaussian_arrays()
    (tmp_path / "skin").mkdir()
    np.savez(tmp_path / "skin" / "crossing.npz", **arrays)
    (tmp_path / "skin" / "summary.json").write_text(json.dumps(summary))
    lines = ["id,i,j,x_mm,y_mm,z_mm"] + [
        f"{n},{n // 12},{n % 12},{16.0 * (n // 12)},{12.0 * (n % 12)},0.0" for n in range(252)
    ]
    (tmp_path / "t.csv").write_text("\n".join(lines) + "\n")
    xyz = np.array([[16.0 * (n // 12), 12.0 * (n % 12), 0.0] for n in range(252)])
    gaps = [2.0, 1.0, 0.0]
    d = np.linalg.norm(xyz - [150.0, 66.0, 0.0], axis=1)
    rows = [np.full(252, 500.0)] * 10 + [
        500.0 + 1.5 * A * np.exp(-0.5 * (d / SIGMA) ** 2) * np.exp(-g / DECAY) for g in gaps
    ]
    frames = np.round(np.stack(rows)).astype(np.int64).reshape(-1, 21, 12)
    write_npz(tmp_path / "f.npz", Recording(frames, np.arange(len(frames)) / 60.0))
    # the table's contact is 1.5 x weaker than these fingers: heights 1.5 decay lengths lower
    scene = default_scene().with_values(
        {"skin.model": "electrostatic", "detection.threshold_counts": 5.0}
    )
    locate_scene(
        scene,
        tmp_path / "f.npz",
        tmp_path / "t.csv",
        None,
        tmp_path / "o",
        crossing_dir=tmp_path / "skin",
    )
    text = (tmp_path / "o" / "touches.csv").read_text().splitlines()
    head = [ln for ln in text if not ln.startswith("#")][0].split(",")
    body = [ln.split(",") for ln in text if ln and not ln.startswith(("#", "frame"))]
    strength = np.array([float(b[head.index("strength")]) for b in body])
    h = np.array([float(b[head.index("height_mm")]) for b in body])
    np.testing.assert_allclose(strength, 1.5 * np.exp(-np.array(gaps) / DECAY), rtol=0.03)
    want = np.maximum(np.array(gaps) - DECAY * np.log(1.5), 0.0)
    np.testing.assert_allclose(h, want, atol=0.05)
