"""Check that the declared dependencies install from wheels on every platform the README
promises: for each machine below, pip resolves pyproject.toml's [project] dependencies at
the tested versions (requirements/constraints.txt) with `--only-binary=:all:` and that
machine's platform tags. pip matches tags exactly, so each machine lists every tag it
accepts (a macOS 14 arm64 machine also takes macosx_11_0_arm64 and universal2 wheels).

The resolution is `pip install --dry-run --target TMP`: the same resolver as `pip
download`, reading the wheels' metadata files from the index instead of downloading the
wheels. Needs network access to the package index.

Run: python .ci/check_wheels.py [--python-version 3.12] [--extra NAME ...]
Prints one line per machine; exit code 1 when a machine has no wheel for some dependency.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NOT_FOUND = re.compile(r"No matching distribution found for (\S+)")


def macos_tags(major: int, arch: str) -> list[str]:
    """The tags a macOS `major`.0 machine on arm64 accepts: arm64 wheels from 11.0 on,
    universal2 wheels from 10.4 on."""
    tags = []
    for v in range(major, 10, -1):
        tags += [f"macosx_{v}_0_{arch}", f"macosx_{v}_0_universal2"]
    return tags + [f"macosx_10_{minor}_universal2" for minor in range(16, 3, -1)]


def manylinux_tags(glibc_minor: int, arch: str) -> list[str]:
    """The tags a Linux machine with glibc 2.`glibc_minor` accepts (with the legacy names
    of manylinux_2_17, 2_12 and 2_5)."""
    tags = [f"manylinux_2_{minor}_{arch}" for minor in range(glibc_minor, 4, -1)]
    legacy = {17: "manylinux2014", 12: "manylinux2010", 5: "manylinux1"}
    return tags + [f"{legacy[m]}_{arch}" for m in legacy if m <= glibc_minor]


MACHINES = {
    "macOS 14 arm64": macos_tags(14, "arm64"),
    "Windows amd64": ["win_amd64"],
    "Linux x86_64 (glibc 2.28)": manylinux_tags(28, "x86_64"),
}


def requirements(extras: list[str]) -> list[str]:
    """The [project] dependencies, and those of the named extras."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = list(project["dependencies"])
    for extra in extras:
        reqs += project["optional-dependencies"][extra]
    return reqs


def resolve(reqs: list[str], tags: list[str], python_version: str) -> tuple[bool, str]:
    """(True, "") when pip finds wheels for every requirement with these tags, else
    (False, pip's last error line)."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [
            sys.executable, "-m", "pip", "install", "--dry-run",
            "--ignore-installed", "--only-binary=:all:", "--target", tmp,
            "--python-version", python_version, "--implementation", "cp",
            "-c", str(ROOT / "requirements" / "constraints.txt"),
        ]  # fmt: skip
        for tag in tags:
            cmd += ["--platform", tag]
        res = subprocess.run(cmd + reqs, capture_output=True, text=True)
    if res.returncode == 0:
        return True, ""
    return False, why(res.stdout + res.stderr)


def why(output: str) -> str:
    """pip's reason in one line: the packages with no wheel for these tags when pip names
    them, else its last error line."""
    lines = output.splitlines()
    missing = [m.group(1) for m in map(NOT_FOUND.search, lines) if m]
    listing = False  # inside pip's indented list of packages with no distribution
    for line in lines:
        if listing and line.startswith("    "):
            missing.append(line.strip())
        else:
            listing = "no matching distributions available" in line
    if missing:
        return "no wheel for " + ", ".join(dict.fromkeys(missing))
    errors = [line for line in lines if line.startswith("ERROR")]
    return (errors or lines or ["pip failed"])[-1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--python-version", default="3.12")
    parser.add_argument("--extra", action="append", default=[], help="also an extra's deps")
    args = parser.parse_args(argv)
    reqs = requirements(args.extra)
    failed = 0
    for machine, tags in MACHINES.items():
        ok, why = resolve(reqs, tags, args.python_version)
        failed += not ok
        print(f"{machine}, Python {args.python_version}: {'wheels for all' if ok else why}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
