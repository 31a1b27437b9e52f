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
