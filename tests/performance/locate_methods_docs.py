"""The detection methods' error against run time for the docs: `fruit study locate` on the
Fruit at rest, the Fruit deformed in its jig and a flat 4 x 4 pad (16 mm pitch, 144 samples
between its crossings), each on benches whose skin the locator does not assume; the three
tables, each stamped with its date, commit and machine, go to docs/data/locate-methods.md
(and the Fruit's plot to docs/data/locate-methods.png).

Run: python tests/performance/locate_methods_docs.py [--out DIR]  (about 40 minutes on
2 cores). Not part of `make bench`: its figures are errors more than times.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
PAD_SCENE = """[scene]
name = "pad-bench"
configuration = "Flat pad"
description = "A flat 80 x 80 x 3 mm pad, 4 x 4 taxels 16 mm apart, on the virtual bench"
[geometry]
pad_size_mm = [80.0, 80.0, 3.0]
[grid]
count = [4, 4]
spacing_x_mm = 16.0
spacing_y_mm = 16.0
[bench]
indenters = ["small", "medium"]
samples = "pad-samples.csv"
"""
# the pad's bench samples: a lattice 4 mm apart over the taxels' square (16 mm pitch, taxels
# at +-8 and +-24 mm), 1/8, 3/8, 5/8 and 7/8 of a pitch off the crossings: 144 points
PAD_SAMPLES_MM = np.arange(-22.0, 22.5, 4.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/locate-methods-docs")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    pad = out / "pad-bench.toml"
    pad.write_text(PAD_SCENE)
    x, y = np.meshgrid(PAD_SAMPLES_MM, PAD_SAMPLES_MM, indexing="ij")
    lines = ["sample,x_mm,y_mm"]
    lines += [f"{k},{a:g},{b:g}" for k, (a, b) in enumerate(zip(x.ravel(), y.ravel(), strict=True))]
    (out / "pad-samples.csv").write_text("\n".join(lines) + "\n")
    scenes = [
        ("The Fruit at rest", ROOT / "pipelines" / "fruit-rest.toml", "rest"),
        ("The Fruit deformed in its jig", ROOT / "pipelines" / "fruit-deformed.toml", "deformed"),
        ("A flat 4 x 4 pad", pad, "pad"),
    ]
    parts = []
    for title, scene, name in scenes:
        dest = out / name
        if dest.exists():
            shutil.rmtree(dest)
        subprocess.run(
            [str(Path(sys.executable).parent / "fruit"), "study", "locate", str(scene),
             "--out", str(dest)],
            check=True,
        )  # fmt: skip
        text = (dest / "locate_methods.md").read_text().splitlines()
        parts += [f"### {title}", "", *text[2:], ""]
    docs = ROOT / "docs" / "data"
    (docs / "locate-methods.md").write_text("\n".join(parts))
    shutil.copy(out / "rest" / "locate_methods.png", docs / "locate-methods.png")
    print(f"written to {docs / 'locate-methods.md'}")


if __name__ == "__main__":
    main()
