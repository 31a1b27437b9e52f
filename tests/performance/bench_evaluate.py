"""Evaluation speed: matching and Table I statistics on 100,000 synthetic samples."""

from __future__ import annotations

import resource
import time

import numpy as np

from fruitcli.evaluation.metrics import summarize


def main():
    rng = np.random.default_rng(0)
    truth = rng.uniform(-75, 75, (100_000, 3))
    meas = truth + rng.normal(0, 2.0, truth.shape)
    t0 = time.perf_counter()
    s = summarize(truth, meas, 152.0)
    dt = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(
        f"summarize 100k samples: {dt * 1e3:.1f} ms; mean {s['mean_mm']:.3f} mm; "
        f"peak RSS {peak:.0f} MB"
    )


if __name__ == "__main__":
    main()
