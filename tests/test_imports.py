"""The package's import structure: every module imports on its own, no import circle
anywhere (imports inside functions included), and each package imports only what its
docstring allows."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "fruitcli"


def module_names() -> list[str]:
    names = []
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def import_graph() -> dict[str, set[str]]:
    """module -> the fruitcli modules it imports (at the top or inside functions)."""
    names = set(module_names())
    graph: dict[str, set[str]] = {}
    for name in names:
        is_pkg = (ROOT / name.replace(".", "/") / "__init__.py").exists()
        path = ROOT / (name.replace(".", "/") + ("/__init__.py" if is_pkg else ".py"))
        package = name if is_pkg else name.rpartition(".")[0]
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                for alias in node.names:
                    full = f"{base}.{alias.name}"
                    found.add(full if full in names else base)
            elif isinstance(node, ast.Import):
                found.update(a.name for a in node.names)
        graph[name] = {m for m in found if m in names and m != name}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_import_circle():
    assert cycles(import_graph()) == []


def test_a_circle_is_found():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


# package -> packages it must not import (what each package's docstring allows)
FORBIDDEN = {
    "fruitcli.geometry": [
        "fruitcli.sensing",
        "fruitcli.workflow",
        "fruitcli.cli",
        "fruitcli.printer",
        "fruitcli.studies",
    ],
    "fruitcli.fem": [
        "fruitcli.sensing",
        "fruitcli.geometry.tracks",
        "fruitcli.workflow",
        "fruitcli.cli",
        "fruitcli.printer",
        "fruitcli.studies",
    ],
    "fruitcli.evaluation": [
        "fruitcli.sensing",
        "fruitcli.fem",
        "fruitcli.geometry",
        "fruitcli.workflow",
        "fruitcli.cli",
    ],
    "fruitcli.sensing.frames": [
        "fruitcli.sensing.detection",
        "fruitcli.sensing.skin",
        "fruitcli.sensing.outputs",
        "fruitcli.sensing.live",
        "fruitcli.fem",
        "fruitcli.geometry",
    ],
    "fruitcli.sensing.outputs": ["fruitcli.sensing.live", "fruitcli.sensing.skin"],
    "fruitcli.sensing.shape": [
        "fruitcli.sensing.live",
        "fruitcli.sensing.outputs",
        "fruitcli.fem",
        "fruitcli.geometry",
    ],
    "fruitcli.sensing": [
        "fruitcli.workflow",
        "fruitcli.cli",
        "fruitcli.printer",
        "fruitcli.studies",
    ],
    "fruitcli.printer": ["fruitcli.workflow", "fruitcli.cli", "fruitcli.studies"],
    "fruitcli.electrostatics": [
        "fruitcli.workflow",
        "fruitcli.cli",
        "fruitcli.printer",
        "fruitcli.studies",
        "fruitcli.sensing.live",
    ],
    "fruitcli.workflow": ["fruitcli.cli"],
    "fruitcli.studies": ["fruitcli.cli"],
}


def test_packages_import_only_what_they_may():
    bad = [
        f"{m} imports {d}"
        for m, deps in sorted(import_graph().items())
        for d in deps
        for pkg, banned in FORBIDDEN.items()
        if (m == pkg or m.startswith(pkg + "."))
        and any(d == b or d.startswith(b + ".") for b in banned)
    ]
    assert bad == []


@pytest.mark.slow
def test_every_module_imports_on_its_own():
    """Each module imported first, with no other fruitcli module loaded (third-party ones
    stay cached), in one fresh interpreter: a circle or a missing dependency fails."""
    code = (
        "import importlib, sys\n"
        "failed = []\n"
        "for name in sys.argv[1:]:\n"
        "    for k in [k for k in sys.modules if k == 'fruitcli' or k.startswith('fruitcli.')]:\n"
        "        del sys.modules[k]\n"
        "    try:\n"
        "        importlib.import_module(name)\n"
        "    except Exception as exc:\n"
        "        failed.append(f'{name}: {type(exc).__name__}: {exc}')\n"
        "print('\\n'.join(failed))\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", code, *module_names()],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.strip() == ""
