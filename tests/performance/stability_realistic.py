"""The stability study's realistic bodies (`fruit study stability --group 'sphere, gmsh'
--group 'fruit, gmsh'`): a gmsh thick sphere and the default Fruit on the default
element, from 5 kPa to 2000 kPa, down to -500 kPa, at E = 1 kPa and 1 GPa and at
nu = 0.4999; each row converged or a named failure, with its time (the budget per row is
60 s). With --docs the rows, date, commit and machine go to
docs/data/stability-realistic.json, from which `make docs` draws the table of
docs/explanation/limits.md.

Run: .venv/bin/python tests/performance/stability_realistic.py [--jobs N] [--docs]
"""

import argparse
import datetime
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
GROUPS = ("sphere, gmsh", "fruit, gmsh")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument(
        "--docs", action="store_true", help="write docs/data/stability-realistic.json"
    )
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    from run_all import commit, processor

    with tempfile.TemporaryDirectory() as tmp:
        fruit = Path(sys.executable).parent / "fruit"
        cmd = [str(fruit), "-q", "study", "stability", "--out", tmp, "--jobs", str(args.jobs)]
        for group in GROUPS:
            cmd += ["--group", group]
        t0 = time.perf_counter()
        code = subprocess.call(
            cmd, cwd=ROOT, env=os.environ | {"MPLBACKEND": "Agg"}, stdout=subprocess.DEVNULL
        )
        wall = time.perf_counter() - t0
        if code:
            sys.exit(f"fruit study stability: exit {code}")
        rows = json.loads((Path(tmp) / "stability.json").read_text())
    slowest = max(r["seconds"] for r in rows)
    print(f"realistic bodies: {len(rows)} rows in {wall:.1f} s (--jobs {args.jobs})")
    print(f"slowest row: {slowest:.1f} s")
    for r in rows:
        print(f"  {r['case']}: {r['seconds']:.1f} s, {r['status'][:90]}")
    if args.docs:
        summary = {
            "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "commit": commit(),
            "machine": f"{processor()}, {os.cpu_count()} cores",
            "jobs": args.jobs,
            "wall_seconds": round(wall, 1),
            "rows": rows,
        }
        path = ROOT / "docs" / "data" / "stability-realistic.json"
        path.write_text(json.dumps(summary, indent=1) + "\n")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
