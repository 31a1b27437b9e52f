"""What checking a stage's outputs before reuse costs: the sha256 of every file of a
stage folder of the size of all of `fruit demo`'s outputs (39 MB in 91 files), as the
planner computes it on every run for each stage it reuses."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from fruitcli.workflow.planner import output_hashes

MB = 1024 * 1024


def main():
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        sizes = [6 * MB, 3 * MB, 3 * MB, 3 * MB, 2 * MB, 2 * MB] + [20 * MB // 85] * 85
        for k, size in enumerate(sizes):
            (folder / f"f{k}.npz").write_bytes(rng.bytes(size))
        total = sum(sizes) / MB
        best = float("inf")
        for _ in range(5):
            t0 = time.perf_counter()
            output_hashes(folder)
            best = min(best, time.perf_counter() - t0)
    print(
        f"outputs checked before reuse: {total:.0f} MB in {len(sizes)} files hashed in "
        f"{best * 1e3:.0f} ms ({total / best:.0f} MB/s)"
    )


if __name__ == "__main__":
    main()
