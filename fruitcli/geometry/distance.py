"""Exact point-to-surface distances on triangle meshes, without rtree.

Candidates come from a KD-tree over vertices (the faces around the k nearest vertices);
each candidate triangle is then measured exactly. Points `(n, 3)` float64, mm.
"""

from __future__ import annotations

import numpy as np

# points per vectorized batch (bounds the memory of the candidate arrays)
CHUNK_POINTS = 20000
# at most this many subdivisions per edge when sampling a large face
MAX_SAMPLE_LEVEL = 24


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray,
                         c: np.ndarray) -> np.ndarray:
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
        out = a + ab * v[:, None] + ac * w[:, None]           # interior
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
    bad = ~np.isfinite(out).all(axis=1)                      # degenerate triangles
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

    def nearest_vertex_distance(self, points: np.ndarray,
                                upper_mm: float = np.inf) -> np.ndarray:
        """Distance (n,) to the nearest vertex (an upper bound of the surface distance)."""
        d, _ = self.tree.query(points, k=1, distance_upper_bound=upper_mm)
        return d

    def closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest surface points (n, 3), distances (n,), face indices (n,)."""
        points = np.asarray(points, dtype=float)
        if len(points) > CHUNK_POINTS:
            parts = [self._closest(points[i:i + CHUNK_POINTS])
                     for i in range(0, len(points), CHUNK_POINTS)]
            return tuple(np.concatenate(x) for x in zip(*parts, strict=True))
        return self._closest(points)

    def _closest(self, points: np.ndarray):
        _, vi = self.tree.query(points, k=self.k)
        vi = vi.reshape(len(points), -1)
        n = len(points)
        start = self.vf_start[vi].ravel()
        count = self.vf_start[vi + 1].ravel() - start
        rows = np.repeat(np.repeat(np.arange(n), vi.shape[1]), count)
        offs = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
        fid = self.vf_faces[np.repeat(start, count) + offs]
        _, si = self.sample_tree.query(points, k=min(self.k, len(self.samples)))
        si = si.reshape(n, -1)
        rows = np.concatenate([rows, np.repeat(np.arange(n), si.shape[1])])
        fid = np.concatenate([fid, self.sample_face[si.ravel()]])
        tri = self.vertices[self.faces[fid]]
        q = closest_on_triangles(points[rows], tri[:, 0], tri[:, 1], tri[:, 2])
        d2 = ((q - points[rows]) ** 2).sum(axis=1)
        best = np.full(n, np.inf)
        np.minimum.at(best, rows, d2)
        is_best = d2 <= best[rows]
        first = np.full(n, -1, dtype=np.int64)
        idx = np.nonzero(is_best)[0]
        first[rows[idx[::-1]]] = idx[::-1]
        return q[first], np.sqrt(best), fid[first]


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
