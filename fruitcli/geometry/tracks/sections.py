"""Plane sections of a triangle mesh, chained into polylines (no networkx needed).

A plane is `coordinate[axis] = value` (axis 0: x = const, axis 1: y = const). Each
section point lies on a mesh edge (or a vertex) and on the plane; consecutive points
lie in one face. Points `(k, 3)` float64 in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Piece:
    """One connected part of a section: points (k, 3) mm, face of each segment (k-1,)."""

    points: np.ndarray
    faces: np.ndarray
    closed: bool

    @property
    def length_mm(self) -> float:
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())


def plane_segments(
    vertices: np.ndarray,
    faces: np.ndarray,
    axis: int,
    value: float,
    face_mask: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Segments of the section: (node ids (m, 2) int, points (m, 2, 3), face ids (m,)).

    A node id names the mesh edge (or vertex) a point lies on, so that the segments of
    neighbouring faces share their end nodes exactly. Vertices on the plane count as
    being on its positive side.
    """
    n_vert = len(vertices)
    s = vertices[:, axis] - value
    pos = s >= 0
    fid = np.arange(len(faces)) if face_mask is None else np.nonzero(face_mask)[0]
    f = faces[fid]
    npos = pos[f].sum(axis=1)
    cross = (npos == 1) | (npos == 2)
    f, fid = f[cross], fid[cross]
    nodes, pts = [], []
    for e0, e1 in ((0, 1), (1, 2), (2, 0)):
        a, b = f[:, e0], f[:, e1]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        sl, sh = s[lo], s[hi]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = sl / (sl - sh)
            p = vertices[lo] + (vertices[hi] - vertices[lo]) * t[:, None]
        node = lo * n_vert + hi
        node = np.where(t == 0, lo * n_vert + lo, np.where(t == 1, hi * n_vert + hi, node))
        p = np.where((t == 0)[:, None], vertices[lo], p)
        p = np.where((t == 1)[:, None], vertices[hi], p)
        nodes.append(np.where(pos[a] != pos[b], node, -1))
        pts.append(p)
    edge_nodes, edge_pts = np.stack(nodes, axis=1), np.stack(pts, axis=1)
    has = edge_nodes >= 0
    # exactly two crossing edges per face: pick them in edge order
    first = np.argmax(has, axis=1)
    second = 2 - np.argmax(has[:, ::-1], axis=1)
    r = np.arange(len(f))
    seg_nodes = np.stack([edge_nodes[r, first], edge_nodes[r, second]], axis=1)
    seg_pts = np.stack([edge_pts[r, first], edge_pts[r, second]], axis=1)
    keep = seg_nodes[:, 0] != seg_nodes[:, 1]
    return seg_nodes[keep], seg_pts[keep], fid[keep]


def chain(seg_nodes: np.ndarray, seg_pts: np.ndarray, seg_faces: np.ndarray) -> list[Piece]:
    """Chain segments sharing end nodes into pieces (open ones first, then loops)."""
    adjacency: dict[int, list[int]] = {}
    point_of: dict[int, np.ndarray] = {}
    for k, (a, b) in enumerate(seg_nodes.tolist()):
        adjacency.setdefault(a, []).append(k)
        adjacency.setdefault(b, []).append(k)
        point_of[a], point_of[b] = seg_pts[k][0], seg_pts[k][1]
    used = np.zeros(len(seg_nodes), dtype=bool)
    pieces: list[Piece] = []
    ends = sorted(n for n, segs in adjacency.items() if len(segs) == 1)
    order = ends + sorted(n for n, segs in adjacency.items() if len(segs) != 1)
    for start in order:
        while True:
            seg = next((k for k in adjacency[start] if not used[k]), None)
            if seg is None:
                break
            node, pts, fcs = start, [point_of[start]], []
            while seg is not None:
                used[seg] = True
                a, b = seg_nodes[seg]
                node = b if a == node else a
                pts.append(point_of[node])
                fcs.append(seg_faces[seg])
                seg = next((k for k in adjacency[node] if not used[k]), None)
            closed = node == start and len(fcs) > 2
            pieces.append(Piece(np.asarray(pts), np.asarray(fcs, dtype=np.int64), closed))
    return pieces


def section_pieces(
    vertices: np.ndarray,
    faces: np.ndarray,
    axis: int,
    value: float,
    face_mask: np.ndarray | None = None,
) -> list[Piece]:
    """Connected pieces of the section `coordinate[axis] = value` over `face_mask` faces."""
    nodes, pts, fid = plane_segments(vertices, faces, axis, value, face_mask)
    return chain(nodes, pts, fid)


def _runs(flags: np.ndarray) -> list[tuple[int, int, bool]]:
    """Runs of equal values in a 1D bool array: (start, stop, value), stop exclusive."""
    cut = np.flatnonzero(np.diff(flags.astype(np.int8))) + 1
    bounds = np.r_[0, cut, len(flags)]
    return [(int(a), int(b), bool(flags[a])) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


def masked_runs(
    piece: Piece, keep: np.ndarray, max_gap_mm: float, min_length_mm: float
) -> list[Piece]:
    """The parts of `piece` whose segments are kept (`keep` (k-1,) bool per segment).

    A mask taken face by face is noisy (a sliver face with a tilted normal breaks a curve
    into two pieces whose ends nearly touch, and the two tubes then leave a bridge over
    the groove), so gaps shorter than `max_gap_mm` between kept parts are kept too, and
    kept parts shorter than `min_length_mm` are dropped.
    """
    keep = np.asarray(keep, dtype=bool).copy()
    seg_len = np.linalg.norm(np.diff(piece.points, axis=0), axis=1)
    if keep.all():
        return [piece] if seg_len.sum() >= min_length_mm else []
    shift = 0
    if not keep.any():
        return []
    if piece.closed:  # start the loop where a dropped part starts
        shift = int(np.flatnonzero(~keep & np.roll(keep, 1))[0])
        keep = np.roll(keep, -shift)
        seg_len = np.roll(seg_len, -shift)
    runs = _runs(keep)
    for n, (a, b, kept) in enumerate(runs):
        inner = piece.closed or 0 < n < len(runs) - 1
        if not kept and inner and seg_len[a:b].sum() < max_gap_mm:
            keep[a:b] = True
    if piece.closed and keep.all():
        return [piece] if seg_len.sum() >= min_length_mm else []
    pts = piece.points[:-1] if piece.closed else piece.points
    fcs = piece.faces
    if piece.closed:  # unroll: segment s runs from point s to s + 1
        pts = np.roll(pts, -shift, axis=0)
        pts = np.concatenate([pts, pts[:1]])
        fcs = np.roll(fcs, -shift)
    out = []
    for a, b, kept in _runs(keep):
        if kept and seg_len[a:b].sum() >= min_length_mm:
            out.append(Piece(pts[a : b + 1], fcs[a:b], False))
    return out
