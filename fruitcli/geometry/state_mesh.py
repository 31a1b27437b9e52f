"""What the geometry and the skin read of a body's FEM states
(`fruitcli.sensing.detection.locate.States`), as a protocol that imports nothing of the
library: the rest mesh and the nodes of a state, in mm."""

from __future__ import annotations

from typing import Protocol

import numpy as np


class StateMesh(Protocol):
    """The rest mesh (nodes mm, tets), its surface triangles and the nodes of a state
    (N, 3) mm."""

    @property
    def rest_nodes(self) -> np.ndarray: ...
    @property
    def tets(self) -> np.ndarray: ...
    @property
    def surface_tris(self) -> np.ndarray: ...
    def nodes_mm(self, state: int) -> np.ndarray: ...
