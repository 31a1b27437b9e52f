"""The package's import structure: every module imports on its own, no import circle
anywhere (imports inside functions included), and each package imports only what its
docstring allows."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from dataclasses import dataclass
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


# ----------------------------------------------------------------------------- the rules
def is_package(name: str) -> bool:
    return (ROOT / name.replace(".", "/") / "__init__.py").exists()


def docstring(package: str) -> str:
    """A package's docstring, its lines joined."""
    text = ast.get_docstring(
        ast.parse((ROOT / package.replace(".", "/") / "__init__.py").read_text())
    )
    return " ".join((text or "").split())


def named(text: str) -> list[str]:
    """The `fruitcli...` names in backquotes of a piece of docstring."""
    return re.findall(r"`(fruitcli(?:\.\w+)+)`", text)


def paragraph(text: str, lead: str) -> str:
    """The sentence of `text` after `lead` up to its full stop ("" when absent)."""
    at = text.find(lead)
    if at < 0:
        return ""
    rest = text[at + len(lead) :]
    return re.split(r"\.(?:\s|$)", rest, maxsplit=1)[0]


@dataclass(frozen=True)
class Rule:
    """What a package's modules may import: the package's own modules (all below it; for
    `fruitcli` its top modules only), the listed names and all below them (`names`), the
    modules directly in a listed package (`tops`), or, for "every package", anything but
    `but`."""

    package: str
    names: tuple[str, ...] = ()
    tops: tuple[str, ...] = ()
    every: bool = False
    but: tuple[str, ...] = ()

    def allows(self, module: str) -> bool:
        if self.package == "fruitcli":
            own = module.count(".") == 1 and not is_package(module)
        else:
            own = module == self.package or module.startswith(self.package + ".")
        if own or any(module == n or module.startswith(n + ".") for n in self.names):
            return True
        if any(module.rpartition(".")[0] == t and not is_package(module) for t in self.tops):
            return True
        return self.every and not any(module == b or module.startswith(b + ".") for b in self.but)


def parse_rule(package: str, text: str) -> Rule | None:
    """The rule of a package docstring's "May import ..." sentence; None without one.

    Forms: "May import: `a`, `b` (why), `c` top modules[; never ...]." and
    "May import every [other] package [of `fruitcli`] but|except `x`."""
    sentence = paragraph(text, "May import")
    if not sentence:
        return None
    allowed = sentence.split(";")[0]
    if allowed.lstrip(" :").startswith("every"):
        _, _, excluded = re.split(r"\b(but|except)\b", allowed + " but ", maxsplit=1)
        return Rule(package, every=True, but=tuple(named(excluded)))
    tops = tuple(re.findall(r"`(fruitcli(?:\.\w+)*)` top modules", allowed))
    names = tuple(n for n in named(allowed) if n not in tops)
    return Rule(package, names, tops)


def the_bottom() -> tuple[list[str], list[str]]:
    """(shared modules, tables of choices), as `fruitcli`'s docstring lists them."""
    text = docstring("fruitcli")
    return named(paragraph(text, "Shared by all:")), named(paragraph(text, "Tables of choices"))


def rules() -> dict[str, Rule]:
    """Every package's rule, with the bottom (shared modules and tables) allowed to all."""
    shared, tables = the_bottom()
    out = {}
    for package in [n for n in module_names() if is_package(n)]:
        rule = parse_rule(package, docstring(package))
        assert rule is not None, f"{package}: its docstring says nothing of what it may import"
        out[package] = Rule(
            package, rule.names + tuple(shared) + tuple(tables), rule.tops, rule.every, rule.but
        )
    return out


def outside_the_rules(graph: dict[str, set[str]], rules: dict[str, Rule]) -> list[str]:
    """One line "module imports dep" per import its package's rule does not allow."""
    bad = []
    for module, deps in sorted(graph.items()):
        package = module if is_package(module) else module.rpartition(".")[0]
        bad += [f"{module} imports {d}" for d in sorted(deps) if not rules[package].allows(d)]
    return bad


def test_packages_import_only_what_their_docstrings_allow():
    assert outside_the_rules(import_graph(), rules()) == []


def test_the_bottom_imports_only_the_bottom():
    """The tables of choices import nothing of `fruitcli` (the scene schema reads them);
    the shared modules import only one another."""
    shared, tables = the_bottom()
    graph = import_graph()
    assert tables and {"fruitcli.errors", "fruitcli.fsutil"} <= set(shared)
    assert {t: graph[t] for t in tables if graph[t]} == {}
    assert {s: graph[s] - set(shared) for s in shared if graph[s] - set(shared)} == {}


SCENE_SCHEMA = ("key", "limits", "sections_body", "sections_mechanics", "sections_sensing")
SCENE_SCHEMA += ("schema", "records")
"""The modules of `fruitcli.scene` that define the keys and their records."""


def test_the_scene_schema_imports_only_the_bottom():
    """The scene's keys, schema and records import only one another, the shared modules
    and the tables of choices (so every package may read them)."""
    shared, tables = the_bottom()
    graph = import_graph()
    schema = {f"fruitcli.scene.{m}" for m in SCENE_SCHEMA}
    allowed = schema | set(shared) | set(tables)
    assert {m: graph[m] - allowed for m in schema if graph[m] - allowed} == {}


def test_importing_the_scene_loads_only_the_bottom():
    """In a fresh interpreter, `import fruitcli.scene` loads no fruitcli module but its
    own, the shared ones, the tables of choices (with their packages, whose `__init__`
    then imports nothing else) and `fem.materials.build` (the [material] check)."""
    shared, tables = the_bottom()
    code = (
        "import sys\n"
        "import fruitcli.scene\n"
        "print(' '.join(m for m in sys.modules if m.startswith('fruitcli')))\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=600
    )
    assert res.returncode == 0, res.stderr[-2000:]
    packages = {t.rsplit(".", k)[0] for t in tables for k in range(1, t.count(".") + 1)}
    allowed = set(shared) | set(tables) | packages | {"fruitcli.fem.materials.build"}
    loaded = {m for m in res.stdout.split() if not m.startswith("fruitcli.scene")}
    assert "fruitcli.fem.elements.families" in loaded and loaded - allowed == set()


def test_the_rules_are_read_as_written():
    """The docstring forms the rules are read from, on toy packages."""
    fem = parse_rule(
        "fruitcli.fem.solver",
        "May import: `fruitcli.fem` top modules, `fruitcli.fem.materials` (its kernels), "
        "`fruitcli.errors`; never `fruitcli.sensing`.",
    )
    assert fem.tops == ("fruitcli.fem",)
    assert fem.names == ("fruitcli.fem.materials", "fruitcli.errors")
    assert fem.allows("fruitcli.fem.units") and fem.allows("fruitcli.fem.solver.newton")
    assert fem.allows("fruitcli.fem.materials.corotation")
    assert not fem.allows("fruitcli.fem.elements") and not fem.allows("fruitcli.sensing")
    assert not fem.allows("fruitcli.fem.elements.lagrange")
    studies = parse_rule("fruitcli.studies", "May import every package but `fruitcli.cli`.")
    assert studies.allows("fruitcli.workflow.stages") and not studies.allows("fruitcli.cli.main")
    cli = parse_rule("fruitcli.cli", "May import every package of `fruitcli`; nothing else.")
    assert cli.allows("fruitcli.workflow") and cli.but == ()
    assert parse_rule("fruitcli.x", "Holds things.") is None
    graph = {"fruitcli.fem.solver.newton": {"fruitcli.fem.elements.lagrange"}}
    assert outside_the_rules(graph, {"fruitcli.fem.solver": fem}) == [
        "fruitcli.fem.solver.newton imports fruitcli.fem.elements.lagrange"
    ]


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
    res = _over_every_module(code)
    assert res.stdout.strip() == ""


def test_no_module_builds_a_scene_at_import():
    """Importing every fruitcli module builds no `Scene` (module-level constants take
    their defaults from the tables and the schema's keys, not from a scene): a fresh
    interpreter counts the Scenes made while the modules are imported, and one made
    afterwards, so the count is seen to work."""
    code = (
        "import importlib, sys\n"
        "import fruitcli.scene as s\n"
        "made = []\n"
        "init = s.Scene.__init__\n"
        "def counting(self, *a, **k):\n"
        "    made.append(1)\n"
        "    init(self, *a, **k)\n"
        "s.Scene.__init__ = counting\n"
        "for name in sys.argv[1:]:\n"
        "    before = len(made)\n"
        "    importlib.import_module(name)\n"
        "    if len(made) > before:\n"
        "        print('at import:', name)\n"
        "s.default_scene()\n"
        "print('made:', len(made))\n"
    )
    res = _over_every_module(code)
    assert res.stdout.splitlines() == ["made: 1"]


def _over_every_module(code: str) -> subprocess.CompletedProcess:
    """`code` run in a fresh interpreter with every fruitcli module's name as argv[1:]
    (it must exit 0)."""
    res = subprocess.run(
        [sys.executable, "-c", code, *module_names()],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    return res
