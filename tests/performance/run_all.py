"""`make bench`: run every benchmark script in this folder, each in its own process,
so one's peak memory does not hide another's. Prints their figures as they come.

With `--json FILE` the figures also go to a machine-readable result: the machine (date,
commit, cores, processor, load average before and after) and, per script, every line it
printed with each number's min / median / max over `--runs` runs. A line is identified
by its text with the numbers taken out (and its place among lines of the same text), so
the scripts need no special output format. `docs/generate.py` makes the documentation's
performance page from that file.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

from fruitcli.studies.machine import processor

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
NUMBER = re.compile(r"(?<![A-Za-z_\d.])[-+]?\d[\d,]*(?:\.\d+)?(?:[eE][-+]?\d+)?(?![A-Za-z_\d])")


def split_line(line: str) -> tuple[str, list[float]]:
    """A printed line as (its text with every number replaced by '{}', the numbers)."""
    numbers = [float(m.group().replace(",", "")) for m in NUMBER.finditer(line)]
    return NUMBER.sub("{}", line.replace("{", "{{").replace("}", "}}")), numbers


def figures(outputs: list[str]) -> list[dict]:
    """Each printed line with numbers, over the runs' outputs: its template and, per number,
    min / median / max and the values (a line missing from some runs has fewer values)."""
    rows: dict[tuple[str, int], list[list[float]]] = {}
    order: list[tuple[str, int]] = []
    for text in outputs:
        seen: dict[str, int] = {}
        for line in text.splitlines():
            template, numbers = split_line(line.rstrip())
            if not numbers:
                continue
            key = (template, seen.get(template, 0))
            seen[template] = key[1] + 1
            if key not in rows:
                rows[key] = []
                order.append(key)
            rows[key].append(numbers)
    out = []
    for key in order:
        runs = rows[key]
        columns = list(zip(*runs, strict=False))
        out.append(
            {
                "line": key[0],
                "occurrence": key[1],
                "runs": len(runs),
                "numbers": [
                    {
                        "min": min(c),
                        "median": statistics.median(c),
                        "max": max(c),
                        "values": list(c),
                    }
                    for c in columns
                ],
            }
        )
    return out


def commit() -> str:
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=ROOT,
            capture_output=True,
            text=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+changes" if dirty else "")


MAX_RUNS = re.compile(r"^MAX_RUNS\s*=\s*(\d+)", re.M)


def runs_of(script: Path, asked: int) -> int:
    """`asked`, or fewer when the script says `MAX_RUNS = n` at its top level (a benchmark
    that takes many minutes, whose figure varies little between runs)."""
    found = MAX_RUNS.search(script.read_text())
    return min(asked, int(found.group(1))) if found else asked


def run_script(script: Path) -> tuple[int, str, float]:
    """Run one benchmark, echoing its output; returns exit code, output, wall seconds."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, str(script)], cwd=ROOT, stdout=subprocess.PIPE, text=True
    )
    lines = []
    assert proc.stdout is not None  # stdout=PIPE
    for line in proc.stdout:
        print(line, end="", flush=True)
        lines.append(line)
    code = proc.wait()
    return code, "".join(lines), time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=1, help="runs of every script (>= 1)")
    parser.add_argument("--json", type=Path, default=None, help="write the result file here")
    parser.add_argument(
        "--only", default=None, help="comma-separated script names (bench_evaluate,...): only these"
    )
    args = parser.parse_args(argv)
    if args.runs < 1:
        parser.error("--runs: expected at least 1")
    scripts = sorted(HERE.glob("bench_*.py"))
    if args.only:
        wanted = {n.strip().removesuffix(".py") for n in args.only.split(",")}
        unknown = wanted - {s.stem for s in scripts}
        if unknown:
            parser.error(
                f"--only: no script {', '.join(sorted(unknown))} (scripts: "
                f"{', '.join(s.stem for s in scripts)})"
            )
        scripts = [s for s in scripts if s.stem in wanted]
    if not scripts:
        print("no benchmarks found")
        return 1
    result = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "commit": commit(),
        "cores": os.cpu_count(),
        "processor": processor(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "runs": args.runs,
        "load_average_before": list(os.getloadavg()),
        "scripts": [],
    }
    failed = []
    for script in scripts:
        outputs, walls, codes = [], [], []
        runs = runs_of(script, args.runs)
        for run in range(runs):
            print(f"\n=== {script.name} (run {run + 1} of {runs}) ===", flush=True)
            code, text, wall = run_script(script)
            print(f"=== {script.name}: exit {code}, {wall:.1f} s wall ===", flush=True)
            outputs.append(text)
            walls.append(wall)
            codes.append(code)
        if any(codes):
            failed.append(script.name)
        result["scripts"].append(
            {
                "name": script.stem,
                "exit_codes": codes,
                "wall_s": {
                    "min": min(walls),
                    "median": statistics.median(walls),
                    "max": max(walls),
                    "values": walls,
                },
                "figures": figures(outputs),
            }
        )
    result["load_average_after"] = list(os.getloadavg())
    if args.json is not None:
        from fruitcli.fsutil import write_json

        write_json(args.json, result)
        print(f"\nresult: {args.json}")
    if failed:
        print(f"\nfailed: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
