"""Gain division on the virtual bench: what dividing each taxel's activation
by its gain changes in localisation error.

The calibrate test's setup (tests/sensing/skin/test_calibrate.py): the 4 x 4 pad,
36 samples over the taxels, the small indenter with a hidden [skin] (footprint 4.5 mm,
80 counts at contact, gap decay 2 mm, noise 1.2 counts) and taxel gains drawn in
1 +- 20 %; per seed `fruit bench`, `fruit calibrate` on its recording, then `fruit locate`
without division, with the calibrated gains.csv, and with the hidden gains themselves.
Error: 3D distance of each sample's strongest touch to its contact point (mm), over the
samples every variant found. `python tests/performance/bench_gain.py [SEEDS]` (default 10).
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from fruitcli.fsutil import write_csv
from fruitcli.scene import load_scene
from fruitcli.sensing.inputs_stage import calibrate_inputs
from fruitcli.sensing.skin import forward
from fruitcli.sensing.skin.calibrate import run_calibrate
from fruitcli.sensing.stages import run_bench
from fruitcli.tables import read_table
from tests.helpers.locate import locate_scene
from tests.sensing.skin.test_calibrate import HIDDEN_SKIN, virtual_bench_scene


def errors(out: Path, truth: Path) -> dict[int, float]:
    """sample -> 3D error (mm) of measured.csv against truth.csv."""
    m = read_table(out / "measured.csv", ["sample", "x_mm", "y_mm", "z_mm"])
    t = read_table(truth, ["sample", "x_mm", "y_mm", "z_mm"])
    want = {
        int(k): np.array([x, y, z])
        for k, x, y, z in zip(t["sample"], t["x_mm"], t["y_mm"], t["z_mm"], strict=True)
    }
    return {
        int(k): float(np.linalg.norm(np.array([x, y, z]) - want[int(k)]))
        for k, x, y, z in zip(m["sample"], m["x_mm"], m["y_mm"], m["z_mm"], strict=True)
    }


def one_seed(tmp: Path, seed: int) -> dict:
    scene_path = virtual_bench_scene(tmp, HIDDEN_SKIN)
    text = scene_path.read_text().replace("seed = 4", f"seed = {seed}")
    scene_path.write_text(text)
    scene = load_scene(scene_path)
    run_bench(scene, tmp / "t.csv", None, tmp / "bench")
    rec = tmp / "bench" / "small"
    files = (rec / "frames.npz", rec / "truth.csv", tmp / "t.csv", tmp / "cal")
    run_calibrate(calibrate_inputs(scene), *files)
    hidden = forward.make_skin(16, seed, forward.SkinParams.from_table(scene.skin)).gain
    assert hidden is not None  # a skin with a gain spread
    write_csv(tmp / "hidden.csv", ["id", "gain"], ([k, float(g)] for k, g in enumerate(hidden)))
    out: dict = {}
    for name, gains in (
        ("plain", None),
        ("calibrated", tmp / "cal" / "gains.csv"),
        ("hidden", tmp / "hidden.csv"),
    ):
        locate_scene(
            scene, rec / "frames.npz", tmp / "t.csv", None, tmp / name, gains_csv=gains, workers=1
        )
        out[name] = errors(tmp / name, rec / "truth.csv")
    out["samples"] = len(read_table(rec / "truth.csv", ["sample"])["sample"])
    return out


def main(seeds: int = 10) -> None:
    print("load average:", ", ".join(f"{x:.1f}" for x in os.getloadavg()))
    names = ("plain", "calibrated", "hidden")
    per: dict[str, list] = {n: [] for n in names}
    paired: dict[str, list] = {n: [] for n in names}
    found = {n: 0 for n in names}
    total = 0
    for seed in range(seeds):
        with tempfile.TemporaryDirectory(prefix="bench-gain-") as tmp:
            r = one_seed(Path(tmp), seed)
        total += r["samples"]
        common = set.intersection(*(set(r[n]) for n in names))
        for n in names:
            found[n] += len(r[n])
            per[n] += list(r[n].values())
            paired[n] += [r[n][k] for k in sorted(common)]
        print(
            f"seed {seed}: mean error plain {np.mean(list(r['plain'].values())):.3f} mm, "
            f"calibrated gains {np.mean(list(r['calibrated'].values())):.3f} mm, hidden "
            f"gains {np.mean(list(r['hidden'].values())):.3f} mm "
            f"({len(r['plain'])}/{len(r['calibrated'])}/{len(r['hidden'])} of "
            f"{r['samples']} samples found)"
        )
    for n in names:
        e = np.array(paired[n])
        print(
            f"{n:>10}: {found[n]}/{total} samples found; on the {len(e)} found by all "
            f"three: mean {e.mean():.3f} mm, median {np.median(e):.3f} mm, p90 "
            f"{np.percentile(e, 90):.3f} mm, max {e.max():.3f} mm"
        )
    d = np.array(paired["calibrated"]) - np.array(paired["plain"])
    print(
        f"dividing by the calibrated gains: error change per sample mean {d.mean():+.3f} mm"
        f" (better on {int((d < 0).sum())}, worse on {int((d > 0).sum())} of {d.size})"
    )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10)
