"""The long fuzzing run (`make fuzz`): every target of fuzz_targets.py for a share of a
time budget; prints the cases tried and the failures per target, and the first failing
input of each. Exit 1 when any target failed.

    python tests/robustness/fuzz_run.py [--seconds TOTAL] [--only NAME] [--markdown FILE]

With --markdown the table is also written to FILE (the reliability page).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from hypothesis import HealthCheck, Phase, given, settings

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # run as a script
from tests.robustness.fuzz_targets import TARGETS


class _OutOfTime(Exception):
    pass


def fuzz(name: str, seconds: float) -> tuple[int, int, str]:
    """(cases tried, cases failed, first failure) of target `name` within `seconds`."""
    strategy, check = TARGETS[name]
    tried, failed, first = 0, 0, ""
    end = time.monotonic() + seconds

    @settings(
        max_examples=10**9,
        deadline=None,
        database=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(strategy())
    def prop(value):
        nonlocal tried, failed, first
        if time.monotonic() > end:
            raise _OutOfTime
        tried += 1
        try:
            check(value)
        except Exception as exc:
            failed += 1
            first = first or f"{exc!r} on {value!r}"[:400]

    while time.monotonic() < end:  # hypothesis stops after its own limits: start again
        try:
            prop()
        except _OutOfTime:
            break
    return tried, failed, first


def _where() -> str:
    """Date, commit and machine of this run, for the page it writes."""
    import datetime
    import os
    import platform
    import subprocess

    root = Path(__file__).resolve().parents[2]
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True
        ).stdout.strip()
    except OSError:
        commit = ""
    date = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    machine = f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"
    return f"{date}, commit {commit or 'unknown'}, {machine}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--seconds",
        type=float,
        default=600.0,
        help="time budget of the whole run (s), shared by the targets",
    )
    parser.add_argument("--only", default=None, help="run this target only")
    parser.add_argument("--markdown", default=None, help="also write the table to this file")
    args = parser.parse_args()
    names = [args.only] if args.only else list(TARGETS)
    share = args.seconds / len(names)
    print(f"{'target':22s} {'cases':>8s} {'failures':>9s}")
    bad, rows = 0, []
    for name in names:
        tried, failed, first = fuzz(name, share)
        bad += failed
        rows.append(f"| {name} | {tried} | {failed} |")
        print(f"{name:22s} {tried:8d} {failed:9d}", flush=True)
        if first:
            print(f"    first failure: {first}")
    print(f"total time budget {args.seconds:g} s; failures {bad}")
    if args.markdown:
        Path(args.markdown).parent.mkdir(parents=True, exist_ok=True)
        Path(args.markdown).write_text(
            "# Reliability: fuzzing\n\nEvery reader and parser given hostile inputs "
            "(tests/robustness/fuzz_targets.py); each case must give a correct result or the "
            "project's own error in one line naming the input. Written by `make fuzz` "
            f"({args.seconds:g} s in all) on {_where()}.\n\n"
            "| target | cases | failures |\n|---|---|---|\n" + "\n".join(rows) + "\n"
        )
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
