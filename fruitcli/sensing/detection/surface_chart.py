"""The body's surface as the model method's chart: where the body is known, a touch's
contact point runs over the body itself, not over the surface its window's taxels span.

Units: mm, grid units (taxel pitches).

`model_fit` maps grid coordinates (a, b) around a touch's peak taxel to 3D by a quadratic
fitted to the window's taxels. Inside the taxels that surface and the body agree to a
fraction of a millimetre; past the grid's last row or column they part: a body that
falls away in a steep flank beyond its last taxels (the Fruit's sides) puts a touch
there up to 10 mm below the quadratic, and a fit on the quadratic can only pull such a
touch back in. Here each node of a lattice over the window, ``SUB`` per grid cell, is
walked over the body's surface from the centre taxel: it sets off along the
quadratic's tangent at the centre (a grid unit: a pitch of surface), its direction
turned into the tangent plane of each face it reaches and its length kept, each step
put back on the surface (its closest point). The model then fits on the bilinear
interpolation of the lattice. Past the last taxels the walk follows the body down its
flank. A chart depends only on the window's taxels and the
state, so it is made once per peak taxel and kept.
"""

from __future__ import annotations

import threading
from typing import Protocol

import numpy as np

SUB = 4  # lattice nodes per grid cell
STEPS_PER_CELL = 8  # steps of the walk over the surface per grid cell of the way


class ClosestPoints(Protocol):
    """The body's surface as a chart reads it (`fruitcli.geometry.mesh.distance`'s
    `SurfaceDistance`)."""

    def closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


class SurfaceChart:
    """Charts of the body's surface in the frame's state for model-method windows of
    `half` cells around each peak taxel: `normal` (F, 3) the faces' unit normals and
    `distance` a `geometry.mesh.distance.SurfaceDistance` over the same faces (as
    `geometry.body_surface.SurfaceProjector` keeps them). `corrections` may run on
    several threads."""

    def __init__(self, normal: np.ndarray, distance: ClosestPoints, half: int):
        self.normal = np.asarray(normal, float)
        self.distance = distance
        self.half = int(half)
        nodes = np.arange(2 * self.half * SUB + 1) / SUB - self.half
        self.a, self.b = (g.ravel() for g in np.meshgrid(nodes, nodes, indexing="ij"))
        self._kept: dict[int, np.ndarray] = {}
        self._lock = threading.Lock()

    def corrections(self, centre: np.ndarray, coef: np.ndarray) -> np.ndarray:
        """The lattices (n, L, L, 3), L = 2 half SUB + 1, of touches whose peak taxels are
        `centre` (n,) and whose quadratic maps are `coef` (n, 6, 3) (`model_kernel`): the
        way from the quadratic to the surface at each node."""
        side = 2 * self.half * SUB + 1
        out = np.empty((len(centre), side, side, 3))
        for row, k in enumerate(np.asarray(centre, np.int64)):
            with self._lock:
                lattice = self._kept.get(int(k))
            if lattice is None:
                lattice = self.lattice(coef[row]).reshape(side, side, 3)
                with self._lock:
                    self._kept[int(k)] = lattice
            out[row] = lattice
        return out

    def lattice(self, coef: np.ndarray) -> np.ndarray:
        """(L * L, 3) mm: the walked surface point minus the quadratic `coef` (6, 3) at
        each lattice node."""
        a, b = self.a, self.b
        here, _, face = self.distance.closest(_quadratic(coef, 0 * a, 0 * b))
        steps = max(1, STEPS_PER_CELL * self.half)
        step = (a[:, None] * coef[1] + b[:, None] * coef[2]) / steps
        size = np.linalg.norm(step, axis=1, keepdims=True)
        for _ in range(steps):
            step = _tangent(step, self.normal[face], size)
            here, _, face = self.distance.closest(here + step)
        return here - _quadratic(coef, a, b)


def _quadratic(coef: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The window's quadratic map (P, 3) mm at grid coordinates a, b (P,)."""
    return np.stack([np.ones_like(a), a, b, a * a, a * b, b * b], axis=1) @ coef


def _tangent(step: np.ndarray, normal: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Steps (P, 3) turned into the planes of unit normals (P, 3) and given lengths
    size (P, 1): the walk's direction carried from face to face. A step along its
    normal keeps its direction."""
    along = step - np.sum(step * normal, axis=1, keepdims=True) * normal
    length = np.linalg.norm(along, axis=1, keepdims=True)
    return np.where(
        length > 1e-9 * np.maximum(size, 1e-300), along * size / np.maximum(length, 1e-300), step
    )
