"""The package's rooms stay small: no module over ``MAX_MODULE_LINES`` lines, and no
function over ``MAX_FUNCTION_LINES`` lines unless its docstring says why it must stay
one piece (the words "one piece")."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "fruitcli"
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 100


def _sources() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def test_no_module_is_longer_than_the_limit():
    long = {
        str(p.relative_to(PACKAGE.parent)): n
        for p in _sources()
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES
    }
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


def long_functions(source: str) -> list[tuple[str, int]]:
    """(name, lines) of the functions in `source` over the limit whose docstring does
    not say why they stay one piece."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            lines = (node.end_lineno or node.lineno) - node.lineno + 1
            doc = ast.get_docstring(node) or ""
            if lines > MAX_FUNCTION_LINES and "one piece" not in " ".join(doc.split()):
                out.append((node.name, lines))
    return out


def test_no_function_is_longer_than_the_limit_without_saying_why():
    long = {
        f"{p.relative_to(PACKAGE.parent)}:{name}": n
        for p in _sources()
        for name, n in long_functions(p.read_text(encoding="utf-8"))
    }
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines: {long}"


def test_a_long_function_passes_only_when_its_docstring_says_why():
    body = "\n".join(f"    x{k} = {k}" for k in range(MAX_FUNCTION_LINES))
    plain = f"def f():\n    '''Sum.'''\n{body}\n"
    said = f"def f():\n    '''Sum; one loop,\n    kept in one piece.'''\n{body}\n"
    assert long_functions(plain) == [("f", MAX_FUNCTION_LINES + 2)]
    assert long_functions(said) == []
