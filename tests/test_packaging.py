"""The wheel as a user installs it: every module and the bundled scenes inside it, `fruit
demo` from an empty folder, `fruit scenes copy` then `fruit run`, bad input in one line.

The wheel is installed into a fresh virtual environment with `--no-deps`; that
environment sees this one's site-packages through a .pth file (so the dependencies are
not downloaded again), while `fruitcli` itself comes from the wheel only.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NAMES = ["fruit-breathing", "fruit-deformed", "fruit-rest", "paper-table", "touchpad-4x4"]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel, built from a copy of the sources (nothing is written into the checkout,
    and no earlier build's leftovers get in)."""
    src = tmp_path_factory.mktemp("src")
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, src / name)
    skip = shutil.ignore_patterns("__pycache__", "generated")
    for name in ("fruitcli", "pipelines", "data"):
        shutil.copytree(ROOT / name, src / name, ignore=skip)
    out = tmp_path_factory.mktemp("wheel")
    build = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--verbose",  # the build backend's warnings, kept in build.log
            "--no-deps",
            "--no-build-isolation",
            "--wheel-dir",
            str(out),
            str(src),
        ],
        check=True,
        capture_output=True,
        text=True,
        cwd=out,
    )
    (out / "build.log").write_text(build.stdout + build.stderr)
    (found,) = out.glob("fruit_touch-*.whl")
    # the source distribution from the same copy, beside the wheel
    code = "import sys; from setuptools import build_meta; build_meta.build_sdist(sys.argv[1])"
    subprocess.run([sys.executable, "-c", code, str(out)], check=True, capture_output=True, cwd=src)
    return found


@pytest.fixture(scope="module")
def fruit_bin(wheel, tmp_path_factory) -> Path:
    venv = tmp_path_factory.mktemp("venv")
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    site = subprocess.run(
        [python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True,
        capture_output=True,
        text=True,
    )
    Path(site.stdout.strip(), "project_deps.pth").write_text(
        sysconfig.get_paths()["purelib"] + "\n"
    )
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "--python",
            str(python),
            "install",
            "--quiet",
            "--ignore-installed",
            "--no-deps",
            str(wheel),
        ],
        check=True,
        capture_output=True,
    )
    # --ignore-installed: this environment's own (editable) fruitcli is visible through the
    # .pth file and must be neither taken as the install nor uninstalled
    return venv / "bin" / "fruit"


def run(fruit_bin: Path, *args, cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # the wheel's code only
    env["MPLBACKEND"] = "Agg"
    return subprocess.run(
        [str(fruit_bin), *map(str, args)],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_wheel_holds_every_module_and_the_bundled_files(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    sources = {p.relative_to(ROOT).as_posix() for p in (ROOT / "fruitcli").rglob("*.py")}
    assert sources - names == set()  # a package missing from pyproject's list fails here
    bundled = {n for n in names if n.startswith("fruitcli/_bundled/")}
    assert bundled == (
        {f"fruitcli/_bundled/pipelines/{n}.toml" for n in NAMES}
        | {
            f"fruitcli/_bundled/data/paper/{p.name}"
            for p in (ROOT / "data" / "paper").glob("*.csv")
        }
    )


def test_installed_demo_runs_from_an_empty_folder(fruit_bin, tmp_path):
    res = run(fruit_bin, "--version", cwd=tmp_path)
    assert res.stdout.strip().startswith("fruit, version ")
    res = run(fruit_bin, "demo", "--out", "out", "--scenes", "paper-table", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    report = (tmp_path / "out" / "report.md").read_text()
    assert "| Rest, small (the paper's figure data) | 29 | already registered: 2.56" in report
    assert (tmp_path / "out" / "scenes" / "paper-table.toml").is_file()


def test_installed_scenes_copy_then_run(fruit_bin, tmp_path):
    res = run(fruit_bin, "scenes", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert [line.split()[0] for line in lines] == NAMES
    assert lines[3].endswith("[stages: evaluate]")
    res = run(fruit_bin, "scenes", "copy", "paper-table", "mine", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    scene = tmp_path / "mine" / "paper-table.toml"
    assert 'truth = "data/paper/paper_rest_truth.csv"' in scene.read_text()
    res = run(fruit_bin, "run", scene, "--out", "out", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    summary = (tmp_path / "out" / "evaluate" / "summary.json").read_text()
    assert '"Rest, small"' in summary


def test_installed_bad_input_is_one_line(fruit_bin, tmp_path):
    res = run(fruit_bin, "scenes", "copy", "no-such", "x", cwd=tmp_path)
    assert res.returncode == 1
    assert res.stderr.strip().splitlines() == [
        f"Error: unknown scene 'no-such' (bundled scenes: {', '.join(NAMES)})"
    ]
    assert not (tmp_path / "x").exists()


def test_lower_bounds_are_the_tested_versions():
    """Every `name>=X` in pyproject.toml is pinned to X in requirements/constraints.txt."""
    import re
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    wanted = list(project["dependencies"])
    for extra in project["optional-dependencies"].values():
        wanted += extra
    pins = dict(
        line.strip().lower().split("==")
        for line in (ROOT / "requirements" / "constraints.txt").read_text().splitlines()
        if "==" in line and not line.startswith("#")
    )
    for spec in wanted:
        name, bound = re.fullmatch(r"([A-Za-z0-9_.-]+)>=([0-9.]+)", spec).groups()
        assert pins[name.lower().replace("_", "-")] == bound, spec


def test_metadata_is_ready_to_publish(wheel):
    """License, classifiers, keywords; no project URL until the project has a public
    address (a placeholder would be published as the project's own); MKL (pypardiso)
    only in the extra `pardiso`; no setuptools warning about a package missing from the
    configuration."""
    from email.parser import HeaderParser

    with zipfile.ZipFile(wheel) as z:
        meta = HeaderParser().parsestr(z.read("fruit_touch-0.1.0.dist-info/METADATA").decode())
    assert meta["License-Expression"] == "GPL-3.0-or-later"
    assert meta["Description-Content-Type"] == "text/markdown"
    assert meta["Keywords"] and meta["Author"]
    classifiers = meta.get_all("Classifier")
    for system in ("MacOS", "Microsoft :: Windows", "POSIX :: Linux"):
        assert f"Operating System :: {system}" in classifiers
    assert meta.get_all("Project-URL") is None
    requires = meta.get_all("Requires-Dist")
    assert 'pypardiso>=0.4.7; extra == "pardiso"' in requires
    assert [r for r in requires if r.startswith(("pypardiso", "mkl")) and "extra" not in r] == []
    assert (
        "is absent from the `packages` configuration"
        not in (wheel.parent / "build.log").read_text()
    )


def test_description_renders(wheel):
    """`twine check --strict` on the wheel and the source distribution: the README
    renders as the package index's long description."""
    pytest.importorskip("twine")
    (sdist,) = wheel.parent.glob("fruit_touch-*.tar.gz")
    res = subprocess.run(
        [sys.executable, "-m", "twine", "check", "--strict", str(wheel), str(sdist)],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 0, res.stdout + res.stderr
    assert res.stdout.count("PASSED") == 2


def test_wheel_check_tags_and_reason():
    """.ci/check_wheels.py (run by CI, with network): the tags each machine accepts, and
    pip's failure told in one line naming the package without a wheel."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("check_wheels", ROOT / ".ci" / "check_wheels.py")
    check = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(check)
    mac = check.macos_tags(14, "arm64")
    assert mac[:2] == ["macosx_14_0_arm64", "macosx_14_0_universal2"]
    assert {"macosx_11_0_arm64", "macosx_10_9_universal2"} <= set(mac)
    assert "macosx_10_16_arm64" not in mac and "macosx_15_0_arm64" not in mac
    linux = check.manylinux_tags(28, "x86_64")
    assert {"manylinux_2_28_x86_64", "manylinux2014_x86_64", "manylinux1_x86_64"} <= set(linux)
    assert "manylinux_2_29_x86_64" not in linux
    pip_output = (
        "ERROR: Cannot install pypardiso==0.4.7 because these package versions have "
        "conflicting dependencies.\n\nThe conflict is caused by:\n"
        "    pypardiso 0.4.7 depends on mkl!=2024.0\n\nAdditionally, some packages in these "
        "conflicts have no matching distributions available for your environment:\n"
        "    mkl\n\nTo fix this you could try to:\n"
        "ERROR: ResolutionImpossible: for help visit https://pip.pypa.io/\n"
    )
    assert check.why(pip_output) == "no wheel for mkl"
    assert check.why("ERROR: No matching distribution found for gmsh==9\n") == (
        "no wheel for gmsh==9"
    )
    assert check.why("ERROR: something else\n") == "ERROR: something else"


def _index_lookalike(name: str) -> str:
    """A name as the package index compares it with existing projects before it accepts a
    new one: case, separators (. _ -) and the look-alikes l, i -> 1 and o -> 0 ignored."""
    name = name.lower()
    for sep in "._-":
        name = name.replace(sep, "")
    return name.replace("l", "1").replace("i", "1").replace("o", "0")


def test_the_distribution_name_is_not_refused_as_too_like_an_existing_project():
    """`fruit-cli` (an unrelated tool) is on the package index, so `fruitcli` would be
    refused as too similar; the distribution is `fruit-touch` (the package and the
    command keep their names)."""
    import tomllib

    from fruitcli import DISTRIBUTION

    with open(ROOT / "pyproject.toml", "rb") as fh:
        assert tomllib.load(fh)["project"]["name"] == DISTRIBUTION
    assert _index_lookalike("fruitcli") == _index_lookalike("fruit-cli")
    assert _index_lookalike(DISTRIBUTION) != _index_lookalike("fruit-cli")
