"""Compare two output folders of `fruit demo` (or `fruit run`) file by file.

    python tests/compare_runs.py OLD NEW [--rtol 1e-9] [--atol 1e-9]

Tables (CSV, Markdown), meshes (STL, MSH, VTU) and text must be byte-identical, except for
run times (the report's "seconds" column, JSON keys that hold times or code hashes) and
the folder of the checkout in absolute paths.
npz arrays must agree within the tolerances (a refactor may change round-off). Pictures
(PNG) are compared by their pixels' size only, since fonts may differ between machines.
Prints one line per file that differs and exits 1 when any does.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import numpy as np

TIME_KEY = re.compile(
    r"(^|_)(s|ms|seconds|time|times|times_s|cpu_times_s|elapsed|when|date|"
    r"hash|sha256|code|commit|machine|version|created)$|_s$|_ms$|^times|^cpu"
)
SKIP_JSON_FILES = {"manifest.json"}  # hashes of inputs and code: differ whenever code does


def _json_strip(obj):
    if isinstance(obj, dict):
        return {k: _json_strip(v) for k, v in obj.items() if not TIME_KEY.search(str(k))}
    if isinstance(obj, list):
        return [_json_strip(v) for v in obj]
    if isinstance(obj, str) and obj.startswith("/"):  # an absolute path: the checkout's
        return "/".join(Path(obj).parts[-3:])  # location does not matter, the file does
    return obj


def _report_strip(text: str) -> str:
    # the per-scene seconds and every "(x.xx s)" or "x.x s" timing
    text = re.sub(r"^\| ([\w-]+) \| [0-9.]+ \|", r"| \1 | - |", text, flags=re.M)
    return re.sub(r"\b\d+(\.\d+)? ?s\b", "<t>", text)


def compare_file(a: Path, b: Path, rtol: float, atol: float) -> str | None:
    """None when the two files agree, else why not."""
    suffix = a.suffix.lower()
    if suffix == ".npz":
        with np.load(a, allow_pickle=False) as za, np.load(b, allow_pickle=False) as zb:
            if set(za.files) != set(zb.files):
                return f"arrays {sorted(set(za.files) ^ set(zb.files))} in one only"
            for k in za.files:
                x, y = za[k], zb[k]
                if x.shape != y.shape or x.dtype.kind != y.dtype.kind:
                    return f"array {k}: {x.shape} {x.dtype} vs {y.shape} {y.dtype}"
                if TIME_KEY.search(k):
                    continue
                if x.dtype.kind in "fc":
                    if not np.allclose(x, y, rtol=rtol, atol=atol, equal_nan=True):
                        return f"array {k}: max difference {np.nanmax(np.abs(x - y)):.3g}"
                elif x.dtype.kind in "US" and x.ndim == 0:
                    try:
                        if _json_strip(json.loads(str(x))) != _json_strip(json.loads(str(y))):
                            return f"array {k}: JSON differs"
                    except ValueError:
                        if str(x) != str(y):
                            return f"array {k} differs"
                elif not np.array_equal(x, y):
                    return f"array {k} differs"
        return None
    if suffix == ".json":
        if a.name in SKIP_JSON_FILES:
            return None
        ja, jb = _json_strip(json.loads(a.read_text())), _json_strip(json.loads(b.read_text()))
        return None if ja == jb else "JSON values differ"
    if suffix == ".png":
        return None if (a.stat().st_size > 0) == (b.stat().st_size > 0) else "empty picture"
    if a.name == "report.md":
        same = _report_strip(a.read_text()) == _report_strip(b.read_text())
        return None if same else "report differs beyond its timings"
    return None if a.read_bytes() == b.read_bytes() else "bytes differ"


def compare(old: Path, new: Path, rtol: float = 1e-9, atol: float = 1e-9) -> list[str]:
    """Lines naming each file that differs or exists in one folder only."""
    fa = {p.relative_to(old) for p in old.rglob("*") if p.is_file()}
    fb = {p.relative_to(new) for p in new.rglob("*") if p.is_file()}
    lines = [f"{p}: only in {old}" for p in sorted(fa - fb)]
    lines += [f"{p}: only in {new}" for p in sorted(fb - fa)]
    for p in sorted(fa & fb):
        why = compare_file(old / p, new / p, rtol, atol)
        if why:
            lines.append(f"{p}: {why}")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old", type=Path)
    ap.add_argument("new", type=Path)
    ap.add_argument("--rtol", type=float, default=1e-9)
    ap.add_argument("--atol", type=float, default=1e-9)
    args = ap.parse_args(argv)
    lines = compare(args.old, args.new, args.rtol, args.atol)
    for line in lines:
        print(line)
    n = sum(1 for p in args.old.rglob("*") if p.is_file())
    print(f"{n} files in {args.old}: {len(lines)} differ")
    return 1 if lines else 0


if __name__ == "__main__":
    sys.exit(main())
