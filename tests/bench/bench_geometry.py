"""Benchmark: make-tracks on the default artist mesh; prints each step's time and peak RSS.

Run: .venv/bin/python tests/bench/bench_geometry.py
"""

import resource
import tempfile
import time
from pathlib import Path


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main() -> None:
    from fruitcli.geometry.artist import write_artist
    from fruitcli.geometry.pipeline import make_tracks

    with tempfile.TemporaryDirectory() as tmp:
        art = Path(tmp) / "fruit.stl"
        t0 = time.perf_counter()
        info = write_artist(art)
        print(f"make-artist: {time.perf_counter() - t0:.2f} s, {info['triangles']} triangles, "
              f"peak RSS {rss_mb():.0f} MB")
        t0 = time.perf_counter()
        report = make_tracks(art, Path(tmp) / "out",
                             progress=lambda m: print(f"  {m}  (peak RSS {rss_mb():.0f} MB)"))
        total = time.perf_counter() - t0
        print(f"make-tracks total: {total:.2f} s (target <= 10 s), peak RSS {rss_mb():.0f} MB "
              f"(target <= 1024 MB)")
        print(f"taxels {report['taxels']}, reduced {report['triangles']['reduced']} triangles, "
              f"Hausdorff {report['offset_error']['hausdorff_mm']:.3f} mm")


if __name__ == "__main__":
    main()
