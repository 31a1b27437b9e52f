"""Inside and outside of any triangle mesh: the generalized winding number.

w(p) is the signed solid angle the surface subtends at p over 4 pi (Jacobson, Kavan and
Sorkine-Hornung 2013), evaluated by fruit's own Barnes-Hut tree (Barill et al. 2018;
`fruitcli.geometry.mesh.solid_angle`), or, on a closed surface's grid, exactly by counting
crossings along vertical lines. For a closed, outward-oriented surface w is 1 inside and
0 outside; across a hole it falls smoothly from 1 to 0, so the region w > 1/2 closes the
hole with a smooth cap; overlapping parts add up (w = 2 where two overlap), so w > 1/2
is their union; an open sheet or a plane never reaches 1/2 away from itself: it has no
inside.

Points are `(n, 3)` float64 in mm.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from fruitcli.geometry.mesh.solid_angle import SolidAngleTree

INSIDE = 0.5
"""A point is inside where its winding number exceeds this."""
DEEP_INSIDE = 0.75
"""A mesh has an inside only if its winding number exceeds this somewhere away from its
surface: a sphere missing a quarter still reaches it at its centre; an open sheet, curved
or not, stays near 1/2 (a wavy sheet reaches 0.5-0.6 on its hollow side)."""
ACCURACY = 2.0
"""Barnes-Hut accuracy: a tree node is expanded (second order) only beyond this many
times its radius (on the default Fruit's grid near its surface: within 0.008 of the exact
sum; 1.5 is twice as fast but 0.03 off, 1.0 0.2 off)."""
EXACT_BAND_SPACINGS = 5.5
"""Grid points nearer than this many grid spacings to a vertex get their own winding
number; farther ones interpolate it from a grid twice as coarse. A coarse cell (diagonal
2 sqrt(3) = 3.5 spacings) then never reaches the surface, even between vertices of
densified edges (at most 3 spacings long), and w, harmonic off the surface, is smooth in
it."""
FACE_SIDE_OFFSET = 1e-4
"""Each face's two sides are probed this fraction of the body's extent off its centre."""
CAP_CLEARANCE_SPACINGS = 1.5
"""Where w crosses 1/2 farther than this many grid spacings from the kept surface, the
crossing is a cap closing a hole (not the surface itself)."""


class Winding:
    """Generalized winding number of one triangle soup (vertices (n, 3), faces (m, 3)).

    The Barnes-Hut tree is built on the first evaluation at points: a closed surface's
    grid (`grid_winding`) needs none."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        self.vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        self.closed = is_closed(self.faces)
        self._tree: SolidAngleTree | None = None

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """Winding numbers (k,) at `points` (k, 3)."""
        if self._tree is None:
            from fruitcli.geometry.mesh.solid_angle import SolidAngleTree

            self._tree = SolidAngleTree(self.vertices, self.faces, ACCURACY)
        return self._tree(points)


def is_closed(faces: np.ndarray) -> bool:
    """Whether every edge is used as often in one direction as in the other (a closed
    surface, however many parts, overlapping or not): then the winding number is an
    integer off the surface and any ray from a point crosses it that many times more
    outward than inward."""
    f = np.asarray(faces, dtype=np.int64)
    if len(f) == 0:
        return False
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    n = int(f.max()) + 1
    lo, hi = e.min(axis=1), e.max(axis=1)
    sign = np.where(e[:, 0] < e[:, 1], 1, -1)
    _, inv = np.unique(lo * n + hi, return_inverse=True)
    return not np.bincount(inv.ravel(), sign).any()


def column_winding(wn: Winding, axes: Sequence[np.ndarray]) -> np.ndarray:
    """Winding number (nx, ny, nz) of a closed surface on the grid `axes`, exact: along
    each vertical line, w at z is the number of crossings above z through faces facing
    up minus those facing down. A line whose crossings do not add up to zero (it grazed
    an edge) is evaluated point by point instead."""
    from fruitcli.geometry.mesh.columns import vertical_hits

    shape = tuple(len(a) for a in axes)
    xy = np.stack(np.meshgrid(axes[0], axes[1], indexing="ij"), axis=-1).reshape(-1, 2)
    col, z, up = vertical_hits(wn.vertices, wn.faces, xy, upward=True)
    sign = np.where(up, 1.0, -1.0)
    # crossings at or below grid level k do not count at k: bin each by the grid levels
    # strictly below it, then sum from the top down
    k = np.searchsorted(axes[2], z, side="left")
    acc = np.bincount(col * (shape[2] + 1) + k, sign, minlength=len(xy) * (shape[2] + 1))
    acc = acc.reshape(len(xy), shape[2] + 1)
    above = np.cumsum(acc[:, ::-1], axis=1)[:, ::-1]
    w = above[:, 1:].reshape(shape)
    bad = np.nonzero(above[:, 0] != 0)[0]
    if len(bad):
        i, j = np.unravel_index(bad, shape[:2])
        pts = np.stack(
            np.broadcast_arrays(axes[0][i][:, None], axes[1][j][:, None], axes[2][None, :]), axis=-1
        ).reshape(-1, 3)
        w[i, j] = wn(pts).reshape(len(bad), shape[2])
    return np.ascontiguousarray(w)


def grid_winding(wn: Winding, axes: Sequence[np.ndarray], near: np.ndarray | None) -> np.ndarray:
    """Winding number on the grid `axes` (x, y, z, uniform spacing), shape (nx, ny, nz).

    A closed surface's is exact along vertical lines (`column_winding`; `near` unused).
    Otherwise points where `near` (same shape) is true are evaluated; the others are interpolated
    trilinearly from a grid of twice the spacing.
    """
    if wn.closed:
        return column_winding(wn, axes)
    if near is None:
        raise ValueError("grid_winding: an open surface needs `near`")
    h = float(axes[0][1] - axes[0][0])
    shape = tuple(len(a) for a in axes)
    coarse = [a[0] + 2.0 * h * np.arange((len(a) + 2) // 2 + 1) for a in axes]
    cp = np.stack(np.meshgrid(*coarse, indexing="ij"), axis=-1).reshape(-1, 3)
    w = wn(cp).reshape(tuple(len(c) for c in coarse))
    for axis, n in enumerate(shape):
        i = np.arange(n)
        lo, t = i // 2, (i % 2) * 0.5
        a = np.take(w, lo, axis=axis)
        b = np.take(w, lo + 1, axis=axis)
        tt = t.reshape([-1 if k == axis else 1 for k in range(3)])
        w = a + (b - a) * tt
    w = np.ascontiguousarray(w)
    idx = np.nonzero(near.ravel())[0]
    if len(idx):
        ijk = np.unravel_index(idx, shape)
        pts = np.c_[axes[0][ijk[0]], axes[1][ijk[1]], axes[2][ijk[2]]]
        w.ravel()[idx] = wn(pts)
    return w


def boundary_faces(wn: Winding, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Faces (m,) bool that bound the inside: w is above 1/2 on one side, below on the
    other. Faces inside the union of overlapping parts, and fins outside everything, are
    not."""
    tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    eps = FACE_SIDE_OFFSET * float(np.ptp(vertices, axis=0).max())
    c = tri.mean(axis=1)
    w = wn(np.concatenate([c + eps * n, c - eps * n])).reshape(2, -1)
    return (w.min(axis=0) < INSIDE) & (w.max(axis=0) > INSIDE)


def cap_points(
    axes: Sequence[np.ndarray], w: np.ndarray, surface_distance: Callable[[np.ndarray], np.ndarray]
) -> np.ndarray:
    """Points (k, 3) where w crosses 1/2 along grid edges farther than
    CAP_CLEARANCE_SPACINGS from the surface: the caps that close the holes.

    `surface_distance(points) -> (k,)` is the distance to the kept surface (mm).
    """
    h = float(axes[0][1] - axes[0][0])
    out = []
    for axis in range(3):
        a = np.take(w, np.arange(w.shape[axis] - 1), axis=axis)
        b = np.take(w, np.arange(1, w.shape[axis]), axis=axis)
        cross = (a - INSIDE) * (b - INSIDE) < 0
        if not cross.any():
            continue
        ijk = np.nonzero(cross)
        t = (INSIDE - a[ijk]) / (b[ijk] - a[ijk])
        p = np.c_[axes[0][ijk[0]], axes[1][ijk[1]], axes[2][ijk[2]]]
        p[:, axis] += t * h
        out.append(p)
    if not out:
        return np.zeros((0, 3))
    p = np.concatenate(out)
    return p[surface_distance(p) > CAP_CLEARANCE_SPACINGS * h]
