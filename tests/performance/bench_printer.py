"""The printer bench's loop through the emulated printer and board at real speeds: seconds
per sample and milliseconds per descent step (move, M400, the next whole frame after it),
for the binary and the ASCII firmware at 115200 baud, moves at their real duration."""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from fruitcli.sensing.frames.recording import read_npz
from tests.printer.test_indentation import Rig, make_scene


def main() -> None:
    for fmt in ("binary", "ascii"):
        with tempfile.TemporaryDirectory() as tmp_name:
            tmp = Path(tmp_name)
            rig = Rig(make_scene(tmp), fmt=fmt, baud=115200, time_scale=1.0)
            t0 = time.perf_counter()
            res = rig.run(tmp / "out")
            dt = time.perf_counter() - t0
            rec = read_npz(tmp / "out" / "small" / "frames.npz")
            assert rec.printer_mm is not None  # the printer bench records its tip
            dz = np.diff(rec.printer_mm[:, 2])
            step = np.isclose(dz, -0.1)  # one descent step between these frames
            per_step = np.diff(rec.t_s)[step]
            print(
                f"{fmt:6s} at 115200 baud: {res['samples']} samples in {dt:5.1f} s "
                f"({dt / res['samples']:.1f} s per sample, moves included), {len(rec)} "
                f"frames; a descent step (G1, M400, the next whole frame after it) takes "
                f"{np.median(per_step) * 1e3:.0f} ms median, "
                f"{np.percentile(per_step, 90) * 1e3:.0f} ms p90 over {step.sum()} steps"
            )


if __name__ == "__main__":
    main()
