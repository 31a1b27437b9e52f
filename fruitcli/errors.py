"""Error types. Library code raises these; the CLI turns them into one-line messages (exit 1)."""


class FruitError(Exception):
    """Root of every error fruit reports to a user as one line."""


class SceneError(FruitError):
    """A scene file is malformed: unknown key, wrong type, missing file."""


class GeometryError(FruitError):
    """A mesh cannot be loaded, repaired, reduced or carved."""


class MeshError(FruitError):
    """Tetrahedralization failed or produced a mesh too poor to solve on."""


class SolverError(FruitError):
    """The FEM did not reach equilibrium, or its inputs are inconsistent."""


class FrameError(FruitError):
    """Capacitive frames or a recording are malformed, or a serial port failed."""


class EvaluationError(FruitError):
    """Truth and measured points cannot be compared."""


ECHO_CHARS = 80
"""Longest echo of a user's value in an error message (characters), so that one line stays
one readable line whatever was given."""

LINE_CHARS = 2000
"""Longest error line printed (characters); longer ones are cut in their middle."""


def echo(value: object, limit: int = ECHO_CHARS) -> str:
    """`repr(value)`, cut to `limit` characters with "…" when longer."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def one_line(text: str, limit: int = LINE_CHARS) -> str:
    """`text` on one line of at most `limit` characters: the start and the end kept (they
    name the input and what was expected), the middle cut to "…"."""
    text = " ".join(text.splitlines())
    if len(text) <= limit:
        return text
    half = (limit - 1) // 2
    return text[:half] + "…" + text[len(text) - (limit - 1 - half) :]
