"""Exact point-to-surface distances on triangle meshes, without rtree.

`SurfaceDistance`: candidates come from a KD-tree over vertices (the faces around the k
nearest vertices) and over samples on the faces; each candidate triangle is then
measured exactly. `TreeDistance`: a bounding-box hierarchy over the triangles searched
branch and bound, exact whatever the triangles' sizes. Points `(n, 3)` float64, mm.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

# points per vectorized batch (bounds the memory of the candidate arrays)
CHUNK_POINTS = 20000
# at most this many subdivisions per edge when sampling a large face
MAX_SAMPLE_LEVEL = 24


def unit_face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normals (F, 3) of triangles `faces` (F, 3) over `vertices` (V, 3), by their
    winding (zero for a degenerate face)."""
    t = np.asarray(vertices, float)[np.asarray(faces, np.int64)]
    normal = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    return normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest points (n, 3) on triangles (a, b, c) (each (n, 3)) to points p (n, 3).

    Vectorized region test over vertices, edges and the interior (Ericson, 5.1.5).
    """
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    bp = p - b
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    cp = p - c
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v = vb / denom
        w = vc / denom
        out = a + ab * v[:, None] + ac * w[:, None]  # interior
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    on_bc = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
    out = np.where(on_bc[:, None], b + (c - b) * np.nan_to_num(t_bc)[:, None], out)
    on_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    out = np.where(on_ac[:, None], a + ac * np.nan_to_num(t_ac)[:, None], out)
    on_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    out = np.where(on_ab[:, None], a + ab * np.nan_to_num(t_ab)[:, None], out)
    out = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, out)
    out = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, out)
    out = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, out)
    bad = ~np.isfinite(out).all(axis=1)  # degenerate triangles
    if bad.any():
        out[bad] = a[bad]
    return out


def _dot(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", x, y)


class SurfaceDistance:
    """Distance queries to one triangle mesh (vertices (n, 3), faces (m, 3)), in mm."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, k_vertices: int = 4):
        from scipy.spatial import cKDTree

        self.vertices = np.asarray(vertices, dtype=float)
        self.faces = np.asarray(faces, dtype=np.int64)
        self.k = int(min(k_vertices, len(self.vertices)))
        self.tree = cKDTree(self.vertices, balanced_tree=False, compact_nodes=False)
        # vertex -> faces in CSR form: faces of vertex v are vf_faces[vf_start[v]:vf_start[v+1]]
        flat = self.faces.ravel()
        order = np.argsort(flat, kind="stable")
        counts = np.bincount(flat, minlength=len(self.vertices))
        self.vf_faces = order // 3
        self.vf_start = np.concatenate([[0], np.cumsum(counts)])
        # samples inside the faces, so that large faces are found even far from their corners
        self.samples, self.sample_face = _face_samples(self.vertices, self.faces)
        self.sample_tree = cKDTree(self.samples, balanced_tree=False, compact_nodes=False)

    def nearest_vertex_distance(self, points: np.ndarray, upper_mm: float = np.inf) -> np.ndarray:
        """Distance (n,) to the nearest vertex (an upper bound of the surface distance)."""
        d, _ = self.tree.query(points, k=1, distance_upper_bound=upper_mm)
        return d

    def closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest surface points (n, 3), distances (n,), face indices (n,)."""
        points = np.asarray(points, dtype=float)
        if len(points) > CHUNK_POINTS:
            parts = [
                self._closest(points[i : i + CHUNK_POINTS])
                for i in range(0, len(points), CHUNK_POINTS)
            ]
            p, d, f = (np.concatenate(x) for x in zip(*parts, strict=True))
            return p, d, f
        return self._closest(points)

    def _closest(self, points: np.ndarray):
        _, vi = self.tree.query(points, k=self.k)
        _, si = self.sample_tree.query(points, k=min(self.k, len(self.samples)))
        n = len(points)
        vi = np.ascontiguousarray(vi.reshape(n, -1), dtype=np.int64)
        si = np.ascontiguousarray(self.sample_face[si.reshape(n, -1)], dtype=np.int64)
        q = np.empty((n, 3))
        d2 = np.empty(n)
        fid = np.empty(n, dtype=np.int64)
        _closest_kernel(
            np.ascontiguousarray(points, dtype=float),
            vi,
            si,
            self.vf_start,
            self.vf_faces,
            self.vertices,
            self.faces,
            q,
            d2,
            fid,
        )
        return q, np.sqrt(d2), fid


@njit(cache=True, nogil=True)
def _closest_point(p, a, b, c, out):
    """Closest point on triangle (a, b, c) to p, written into out (Ericson, 5.1.5)."""
    ab0, ab1, ab2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    ac0, ac1, ac2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    ap0, ap1, ap2 = p[0] - a[0], p[1] - a[1], p[2] - a[2]
    d1 = ab0 * ap0 + ab1 * ap1 + ab2 * ap2
    d2 = ac0 * ap0 + ac1 * ap1 + ac2 * ap2
    if d1 <= 0.0 and d2 <= 0.0:
        out[0], out[1], out[2] = a[0], a[1], a[2]
        return
    bp0, bp1, bp2 = p[0] - b[0], p[1] - b[1], p[2] - b[2]
    d3 = ab0 * bp0 + ab1 * bp1 + ab2 * bp2
    d4 = ac0 * bp0 + ac1 * bp1 + ac2 * bp2
    if d3 >= 0.0 and d4 <= d3:
        out[0], out[1], out[2] = b[0], b[1], b[2]
        return
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0 and d1 - d3 != 0.0:
        v = d1 / (d1 - d3)
        out[0], out[1], out[2] = a[0] + v * ab0, a[1] + v * ab1, a[2] + v * ab2
        return
    cp0, cp1, cp2 = p[0] - c[0], p[1] - c[1], p[2] - c[2]
    d5 = ab0 * cp0 + ab1 * cp1 + ab2 * cp2
    d6 = ac0 * cp0 + ac1 * cp1 + ac2 * cp2
    if d6 >= 0.0 and d5 <= d6:
        out[0], out[1], out[2] = c[0], c[1], c[2]
        return
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0 and d2 - d6 != 0.0:
        w = d2 / (d2 - d6)
        out[0], out[1], out[2] = a[0] + w * ac0, a[1] + w * ac1, a[2] + w * ac2
        return
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0 and (d4 - d3) + (d5 - d6) != 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        out[0] = b[0] + w * (c[0] - b[0])
        out[1] = b[1] + w * (c[1] - b[1])
        out[2] = b[2] + w * (c[2] - b[2])
        return
    denom = va + vb + vc
    if denom == 0.0:  # degenerate triangle
        out[0], out[1], out[2] = a[0], a[1], a[2]
        return
    v = vb / denom
    w = vc / denom
    out[0] = a[0] + ab0 * v + ac0 * w
    out[1] = a[1] + ab1 * v + ac1 * w
    out[2] = a[2] + ab2 * v + ac2 * w


@njit(cache=True, nogil=True)
def _closest_kernel(points, vi, si, vf_start, vf_faces, vertices, faces, q, d2, fid):
    """For each point, the closest point over the faces around its nearest vertices
    (vi (n, k)) and the faces of its nearest face samples (si (n, k), face ids)."""
    tmp = np.empty(3)
    for i in range(points.shape[0]):
        p = points[i]
        best = np.inf
        for kk in range(vi.shape[1] + si.shape[1]):
            if kk < vi.shape[1]:
                v = vi[i, kk]
                lo, hi = vf_start[v], vf_start[v + 1]
            else:
                lo, hi = 0, 1
            for t in range(lo, hi):
                f = vf_faces[t] if kk < vi.shape[1] else si[i, kk - vi.shape[1]]
                _closest_point(
                    p, vertices[faces[f, 0]], vertices[faces[f, 1]], vertices[faces[f, 2]], tmp
                )
                e = (tmp[0] - p[0]) ** 2 + (tmp[1] - p[1]) ** 2 + (tmp[2] - p[2]) ** 2
                if e < best:
                    best = e
                    q[i, 0], q[i, 1], q[i, 2] = tmp[0], tmp[1], tmp[2]
                    fid[i] = f
        d2[i] = best


def _face_samples(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points on each face (its centroid, and a barycentric grid on faces much longer than
    the median edge); returns (points (s, 3), face index (s,))."""
    tri = vertices[faces]
    edges = np.linalg.norm(tri - tri[:, [1, 2, 0]], axis=2)
    spacing = max(float(np.median(edges)), 1e-9)
    level = np.clip(np.ceil(edges.max(axis=1) / spacing), 1, MAX_SAMPLE_LEVEL).astype(int)
    pts = [tri.mean(axis=1)]
    fids = [np.arange(len(faces))]
    for lv in np.unique(level[level > 1]):
        sel = np.nonzero(level == lv)[0]
        i, j = np.meshgrid(np.arange(lv + 1), np.arange(lv + 1), indexing="ij")
        keep = (i + j) <= lv
        bary = np.c_[i[keep], j[keep]] / lv
        w = np.c_[1.0 - bary.sum(axis=1), bary]
        p = np.einsum("sk,fkd->fsd", w, tri[sel])
        pts.append(p.reshape(-1, 3))
        fids.append(np.repeat(sel, len(w)))
    return np.concatenate(pts), np.concatenate(fids)


class TreeDistance:
    """Exact distance queries to one triangle mesh (vertices (n, 3), faces (m, 3)), in mm,
    through a bounding-box hierarchy (of faces exactly equally near, the lower index)."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        from scipy.spatial import cKDTree

        from fruitcli.geometry.mesh.solid_angle import LEAF_TRIANGLES, _build_tree

        self.vertices = np.asarray(vertices, dtype=float)
        self.faces = np.asarray(faces, dtype=np.int64)
        self.tree = cKDTree(self.vertices, balanced_tree=False, compact_nodes=False)
        tri = self.vertices[self.faces]
        self.perm, self.start, self.end, self.child = _build_tree(
            np.ascontiguousarray(tri.mean(axis=1)), LEAF_TRIANGLES
        )
        self.tri = np.ascontiguousarray(tri[self.perm].reshape(-1, 9))
        self.lo, self.hi = _node_boxes(self.tri, self.start, self.end, self.child)

    def nearest_vertex_distance(self, points: np.ndarray, upper_mm: float = np.inf) -> np.ndarray:
        """Distance (n,) to the nearest vertex (an upper bound of the surface distance)."""
        d, _ = self.tree.query(points, k=1, distance_upper_bound=upper_mm)
        return d

    def closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest surface points (n, 3), distances (n,), face indices (n,)."""
        pts = np.ascontiguousarray(points, dtype=float).reshape(-1, 3)
        q = np.zeros((len(pts), 3))
        d2 = np.zeros(len(pts))
        fid = np.zeros(len(pts), dtype=np.int64)
        if len(pts):
            _tree_closest(
                pts,
                self.tri,
                self.perm,
                self.start,
                self.end,
                self.child,
                self.lo,
                self.hi,
                q,
                d2,
                fid,
            )
        return q, np.sqrt(d2), fid


@njit(cache=True, nogil=True)
def _node_boxes(t, start, end, child):
    """Each node's bounding box (lo (n, 3), hi (n, 3)) over its triangles' corners."""
    n = start.shape[0]
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    for nd in range(n - 1, -1, -1):
        if child[nd] < 0:
            for k in range(start[nd], end[nd]):
                for v in range(3):
                    for d in range(3):
                        lo[nd, d] = min(lo[nd, d], t[k, 3 * v + d])
                        hi[nd, d] = max(hi[nd, d], t[k, 3 * v + d])
        else:
            for c in (child[nd], child[nd] + 1):
                for d in range(3):
                    lo[nd, d] = min(lo[nd, d], lo[c, d])
                    hi[nd, d] = max(hi[nd, d], hi[c, d])
    return lo, hi


@njit(cache=True, nogil=True)
def _box_d2(p, lo, hi, nd):
    """Squared distance from p to node nd's box (0 inside)."""
    s = 0.0
    for d in range(3):
        if p[d] < lo[nd, d]:
            s += (lo[nd, d] - p[d]) ** 2
        elif p[d] > hi[nd, d]:
            s += (p[d] - hi[nd, d]) ** 2
    return s


@njit(cache=True, nogil=True)
def _tree_closest(points, t, perm, start, end, child, lo, hi, q, d2, fid):
    """Branch and bound: the nearer child first, boxes farther than the best skipped."""
    stack = np.empty(256, np.int64)
    tmp = np.empty(3)
    for i in range(points.shape[0]):
        p = points[i]
        best = np.inf
        best_f = -1
        stack[0] = 0
        top = 1
        while top > 0:
            top -= 1
            nd = stack[top]
            if _box_d2(p, lo, hi, nd) > best:
                continue
            if child[nd] < 0:
                for k in range(start[nd], end[nd]):
                    _closest_point(p, t[k, 0:3], t[k, 3:6], t[k, 6:9], tmp)
                    e = (tmp[0] - p[0]) ** 2 + (tmp[1] - p[1]) ** 2 + (tmp[2] - p[2]) ** 2
                    f = perm[k]
                    if e < best or (e == best and f < best_f):
                        best, best_f = e, f
                        q[i, 0], q[i, 1], q[i, 2] = tmp[0], tmp[1], tmp[2]
                continue
            a, b = child[nd], child[nd] + 1
            if _box_d2(p, lo, hi, a) < _box_d2(p, lo, hi, b):
                a, b = b, a
            stack[top] = a  # the farther child waits
            stack[top + 1] = b
            top += 2
        d2[i] = best
        fid[i] = best_f


def grid_vertex_distance(
    vertices: np.ndarray, axes: Sequence[np.ndarray], upper_mm: float
) -> np.ndarray:
    """Distance (nx * ny * nz,) from each point of the grid `axes` (x, y, z; uniform
    spacing, C order) to the nearest of `vertices` (n, 3), inf where none is nearer than
    `upper_mm`: what a KD-tree query bounded by `upper_mm` gives, found by visiting, for
    each vertex, the grid points within `upper_mm` of it."""
    ax = [np.ascontiguousarray(a, dtype=float) for a in axes]
    d2 = np.full(len(ax[0]) * len(ax[1]) * len(ax[2]), np.inf)
    _splat_nearest(
        np.ascontiguousarray(vertices, dtype=float), ax[0], ax[1], ax[2], float(upper_mm), d2
    )
    d = np.sqrt(d2)
    d[d >= upper_mm] = np.inf
    return d


@njit(cache=True, nogil=True)
def _splat_nearest(vertices, xs, ys, zs, upper, d2):
    nx, ny, nz = xs.shape[0], ys.shape[0], zs.shape[0]
    hx, hy, hz = xs[1] - xs[0], ys[1] - ys[0], zs[1] - zs[0]
    u2 = upper * upper
    for v in range(vertices.shape[0]):
        px, py, pz = vertices[v, 0], vertices[v, 1], vertices[v, 2]
        i0 = max(int(np.floor((px - upper - xs[0]) / hx)), 0)
        i1 = min(int(np.ceil((px + upper - xs[0]) / hx)), nx - 1)
        j0 = max(int(np.floor((py - upper - ys[0]) / hy)), 0)
        j1 = min(int(np.ceil((py + upper - ys[0]) / hy)), ny - 1)
        k0 = max(int(np.floor((pz - upper - zs[0]) / hz)), 0)
        k1 = min(int(np.ceil((pz + upper - zs[0]) / hz)), nz - 1)
        for i in range(i0, i1 + 1):
            dx = xs[i] - px
            for j in range(j0, j1 + 1):
                dy = ys[j] - py
                dxy = dx * dx + dy * dy
                if dxy >= u2:
                    continue
                base = (i * ny + j) * nz
                for k in range(k0, k1 + 1):
                    dz = zs[k] - pz
                    e = dxy + dz * dz
                    if e < d2[base + k]:
                        d2[base + k] = e
