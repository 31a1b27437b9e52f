"""Split a closed triangle surface into two disk patches that gmsh can reparametrize.

gmsh remeshes a discrete surface at a new size only after `createGeometry()` has given
it a parametrization, which needs a topological disk with its boundary split into
curves. A closed (genus 0) shell is cut along triangle edges into a bottom patch and a
top patch; their shared loop is split into two curves at its min-x and max-x vertices.
The bottom patch is the flat base when the solid stands on one (the reduced fruit),
otherwise the faces below the middle of the bounding box. Pure numpy, deterministic.

A selection of whole triangles has a jagged boundary: where one patch meets a loop
vertex with a thin wedge (the reduced fruit's base had a 34 degree spike at its max-x
vertex), gmsh's remeshed curve cuts across the wedge in one patch's parametrization and
the two remeshed patches overlap ("PLC Error: A segment and a facet intersect" at size
6.25). `smooth_selection` moves the triangles of every wedge narrower than
`MIN_CORNER_DEG` to the other patch before the split.
"""

from __future__ import annotations

import numpy as np

from fruitcli.fem.meshing.topology import shells

BASE_NORMAL_Z = -0.9
"""Faces whose outward normal has n_z below this (within 26 deg of straight down) and
that lie in the lowest `BASE_BAND` of the height may belong to the base."""

BASE_BAND = 0.03
"""Height band above the lowest point, as a fraction of the solid's height, searched
for base faces."""

BASE_FLATNESS = 0.05
"""A bottom patch is a flat base (tagged) when its z extent is below this fraction of its
extent in x and y (the reduced fruit: 1.6 mm over 45 mm; a ball's bottom cap: 9 %)."""


MIN_CORNER_DEG = 75.0
"""Smallest corner (sum of triangle angles at a loop vertex on one side) a patch keeps;
a staircase of a regular grid has 90 and 270 degree corners."""

SMOOTH_PASSES = 20
"""At most this many passes of `smooth_selection` (each flips the wedges it finds)."""


def boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """Ordered vertex cycles of the boundary edges of a patch (oriented along the
    patch's winding). Each cycle starts at its smallest vertex index."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    bnd = e[counts[inv.ravel()] == 1]
    if len(bnd) == 0:
        return []
    nxt = dict(zip(bnd[:, 0].tolist(), bnd[:, 1].tolist(), strict=True))
    if len(nxt) != len(bnd):  # a vertex where the boundary touches itself
        return [bnd[:, 0]] * 2
    loops, seen = [], set()
    for start in sorted(nxt):
        if start in seen:
            continue
        cyc, v = [], start
        while v not in seen:
            seen.add(v)
            cyc.append(v)
            v = nxt.get(v)
            if v is None:
                return [bnd[:, 0]] * 2
        loops.append(np.array(cyc, np.int64))
    return loops


def is_disk(faces: np.ndarray) -> bool:
    """One edge-connected piece with Euler characteristic 1 and one boundary loop."""
    if len(faces) == 0 or len(np.unique(shells(faces))) != 1:
        return False
    n_v = len(np.unique(faces))
    n_e = len(
        np.unique(
            np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1),
            axis=0,
        )
    )
    return n_v - n_e + len(faces) == 1 and len(boundary_loops(faces)) == 1


def _close_holes(seed: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The bottom selection grown by every piece of its complement except the largest,
    so that the complement (the top) is one piece."""
    rest = np.flatnonzero(~seed)
    if len(rest) == 0:
        return seed
    lab = shells(faces[rest])
    counts = np.bincount(lab)
    keep = rest[lab == int(np.argmax(counts))]
    out = np.ones(len(faces), bool)
    out[keep] = False
    return out


def corner_angles(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(f, 3) angle (radians) of each triangle at each of its corners."""
    p = np.asarray(vertices, float)[faces]
    out = np.empty((len(faces), 3))
    for k in range(3):
        a = p[:, (k + 1) % 3] - p[:, k]
        b = p[:, (k + 2) % 3] - p[:, k]
        cos = np.einsum("ij,ij->i", a, b) / np.maximum(
            np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), np.finfo(float).tiny
        )
        out[:, k] = np.arccos(np.clip(cos, -1.0, 1.0))
    return out


def smooth_selection(vertices: np.ndarray, faces: np.ndarray, sel: np.ndarray) -> np.ndarray:
    """The face selection `sel` (f,) bool with its wedges removed: at a vertex where the
    selected triangles (or the others) span less than MIN_CORNER_DEG, those triangles
    change side. Passes alternate (grow the selection, then shrink it) until nothing
    changes; a pass that would leave either side empty is not applied."""
    faces = np.asarray(faces, np.int64)
    ang = corner_angles(vertices, faces).ravel()
    vert = faces.ravel()
    owner = np.repeat(np.arange(len(faces)), 3)
    n_v = int(vert.max()) + 1
    limit = np.radians(MIN_CORNER_DEG)
    sel = np.asarray(sel, bool).copy()
    idle = 0
    for step in range(2 * SMOOTH_PASSES):
        grow = step % 2 == 0
        inside = sel[owner]
        a_in = np.bincount(vert, ang * inside, n_v)
        a_out = np.bincount(vert, ang * ~inside, n_v)
        on_loop = (a_in > 0) & (a_out > 0)
        narrow = on_loop & ((a_out if grow else a_in) < limit)
        flip = np.zeros(len(faces), bool)
        flip[owner[narrow[vert] & (inside != grow)]] = True
        new = sel | flip if grow else sel & ~flip
        idle = 0 if flip.any() else idle + 1
        if idle == 2:  # neither growing nor shrinking changes anything
            break
        if new.any() and not new.all():
            sel = new
    return sel


def split_bottom_top(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, bool] | None:
    """(f,) bool, True for the bottom patch, and whether it is a flat base; None when
    neither the base nor the lower half gives two disks (the surface is then kept)."""
    v, f = np.asarray(vertices, float), np.asarray(faces, np.int64)
    p = v[f]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), np.finfo(float).tiny)
    zc = p[:, :, 2].mean(axis=1)
    zmin, zmax = v[:, 2].min(), v[:, 2].max()
    candidates = []
    low = (zc < zmin + BASE_BAND * (zmax - zmin)) & (n[:, 2] < BASE_NORMAL_Z)
    if low.any():
        idx = np.flatnonzero(low)
        lab = shells(f[idx])
        seed = np.zeros(len(f), bool)
        seed[idx[lab == lab[int(np.argmin(zc[idx]))]]] = True
        candidates.append((_close_holes(seed, f), True))
    candidates.append((_close_holes(zc < 0.5 * (zmin + zmax), f), False))
    for bottom, base in candidates:
        smooth = _close_holes(smooth_selection(v, f, bottom), f)
        if is_disk(f[smooth]) and is_disk(f[~smooth]):
            bottom = smooth
        if bottom.all() or not bottom.any() or not is_disk(f[bottom]) or not is_disk(f[~bottom]):
            continue
        bv = v[np.unique(f[bottom])]
        ext = bv.max(axis=0) - bv.min(axis=0)
        if base and ext[2] >= BASE_FLATNESS * min(ext[0], ext[1]):
            continue
        return bottom, base
    return None


def split_loop(loop: np.ndarray, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two vertex paths covering a closed loop, both from its min-x vertex to its max-x
    vertex (ties broken by the smaller index): along the loop and against it."""
    x = vertices[loop, 0]
    i = int(np.lexsort((loop, x))[0])
    j = int(np.lexsort((loop, -x))[0])
    rolled = np.roll(loop, -i)
    k = (j - i) % len(loop)
    forward = rolled[: k + 1]
    backward = np.concatenate([rolled[k:], rolled[:1]])[::-1]
    return forward, backward
