"""Densify: split a closed mesh's long edges until none is longer than asked (same
surface, conforming, winding kept), so that the distance grid of `reduce` bounds
distances well on long triangles. Lengths in mm.
"""

from __future__ import annotations

import numpy as np

# densify: passes at one edge length, and the factor the edge grows by when the face cap
# would be exceeded
DENSIFY_MAX_PASSES = 32
DENSIFY_RELAX = 1.25


def densify(
    vertices: np.ndarray, faces: np.ndarray, max_edge_mm: float, max_faces: int | None = None
) -> tuple[np.ndarray, np.ndarray, float | None]:
    """Split the long edges of a closed mesh until none is longer than `max_edge_mm`
    (same surface, conforming, winding kept).

    The distance grid bounds distances by the nearest vertex before measuring exactly near
    the offset level; on long triangles (a CAD box, a cylinder's side) that bound is far off
    and the offset would come out wrong. Faces whose three edges are long are cut in four
    (midpoints); then each long edge is cut into equal pieces and its faces re-triangulated
    as a fan (one long edge) or a ladder (two long edges), so that a long thin strip
    becomes about 2 L / max_edge_mm faces, not slivers across its width as well.

    If that would give more than `max_faces` faces, the edge length is relaxed until it
    does not. Returns (vertices, faces, edge_mm): the edge length reached, None if no edge
    was split.
    """
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    if _edges(v, f)[2].max() <= max_edge_mm:
        return v, f, None
    cap = np.inf if max_faces is None else max(int(max_faces), len(f))
    edge = float(max_edge_mm)
    while True:
        out = _split_long(v, f, edge, cap)
        if out is not None:
            return out[0], out[1], edge
        edge *= DENSIFY_RELAX


def _edges(v: np.ndarray, f: np.ndarray):
    """Unique edges (e, 2) (low vertex first), face -> edge ids (m, 3) for edges ab, bc, ca,
    and edge lengths (e,)."""
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, first, inv = np.unique(e[:, 0] * len(v) + e[:, 1], return_index=True, return_inverse=True)
    ue = e[first]
    return ue, inv.reshape(3, -1).T, np.linalg.norm(v[ue[:, 0]] - v[ue[:, 1]], axis=1)


def _split_long(v: np.ndarray, f: np.ndarray, edge: float, cap: float):
    """`densify` at one edge length; None as soon as the faces would exceed `cap`."""
    for _ in range(DENSIFY_MAX_PASSES):
        ue, fe, length = _edges(v, f)
        long_ = length[fe] > edge
        if not long_.any():
            break
        fat = long_.all(axis=1)
        if fat.any():
            # a fat face's edges are cut at their midpoints (each cut adds two faces)
            mid = np.full(len(ue), -1, dtype=np.int64)
            cut = np.unique(fe[fat])
            if len(f) + 2 * len(cut) > cap:
                return None
            mid[cut] = len(v) + np.arange(len(cut))
            v = np.concatenate([v, 0.5 * (v[ue[cut, 0]] + v[ue[cut, 1]])])
            f = _split_midpoints(v, f, mid[fe])
            continue
        # each face has at most two long edges: cut them into n equal pieces; on a
        # two-long-edge face the pieces are short enough for its ladder's diagonals
        n_long = long_.sum(axis=1)
        fl = length[fe]
        short = np.where(long_, np.inf, fl).min(axis=1)
        step = np.where(n_long == 2, np.sqrt(np.maximum(edge**2 - short**2, 0.5 * edge**2)), edge)
        pieces = np.ones(len(ue), dtype=np.int64)
        need = np.ceil(fl / step[:, None]).astype(np.int64)
        np.maximum.at(pieces, fe[long_], need[long_])
        pf = pieces[fe]
        count = np.where(n_long == 2, pf.sum(axis=1) - 2, np.maximum(pf.max(axis=1), 1))
        if count.sum() > cap:
            return None
        v, f = _split_pieces(v, f, ue, fe, pieces)
    return v, f


def _split_midpoints(v: np.ndarray, f: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Faces (a, b, c) split at the midpoints m (k, 3) of their edges ab, bc, ca (-1: none)."""
    marked = m >= 0
    n = marked.sum(axis=1)
    out = [f[n == 0]]
    # rotate each face so that its cut edge is ab (one cut) or its uncut edge is ca (two
    # cuts); rotation by r maps edge j to edge (j + r) % 3
    r = np.where(n == 1, np.argmax(marked, axis=1), (np.argmin(marked, axis=1) + 1) % 3)
    idx = (np.arange(3)[None, :] + r[:, None]) % 3
    rf = np.take_along_axis(f, idx, axis=1)
    rm = np.take_along_axis(m, idx, axis=1)
    one, two, three = n == 1, n == 2, n == 3
    a, b, c = rf[one].T
    p = rm[one, 0]
    out += [np.c_[a, p, c], np.c_[p, b, c]]
    a, b, c = rf[two].T
    p, q = rm[two, 0], rm[two, 1]
    out.append(np.c_[p, b, q])
    # the quad a p q c: cut along its shorter diagonal
    aq = np.linalg.norm(v[a] - v[q], axis=1) <= np.linalg.norm(v[p] - v[c], axis=1)
    out += [
        np.where(aq[:, None], np.c_[a, p, q], np.c_[a, p, c]),
        np.where(aq[:, None], np.c_[a, q, c], np.c_[p, q, c]),
    ]
    a, b, c = rf[three].T
    p, q, s = rm[three].T
    out += [np.c_[a, p, s], np.c_[p, b, q], np.c_[s, q, c], np.c_[p, q, s]]
    return np.concatenate(out).astype(np.int64)


def _split_pieces(v: np.ndarray, f: np.ndarray, ue: np.ndarray, fe: np.ndarray, pieces: np.ndarray):
    """Cut edge k into pieces[k] equal parts; faces with one cut edge become a fan from the
    opposite corner, faces with two a ladder between them. Returns (vertices, faces)."""
    cut = np.nonzero(pieces > 1)[0]
    inner = pieces[cut] - 1
    start = np.full(len(ue), -1, dtype=np.int64)
    start[cut] = len(v) + np.concatenate([[0], np.cumsum(inner)[:-1]])
    k = np.arange(inner.sum()) - np.repeat(np.cumsum(inner) - inner, inner) + 1
    e = np.repeat(cut, inner)
    t = (k / pieces[e])[:, None]
    v = np.concatenate([v, v[ue[e, 0]] + (v[ue[e, 1]] - v[ue[e, 0]]) * t])

    def chain(x: int, y: int, eid: int) -> list[int]:
        """Vertex ids from x to y along edge eid."""
        ids = list(range(start[eid], start[eid] + pieces[eid] - 1)) if pieces[eid] > 1 else []
        return [x, *ids, y] if x == ue[eid, 0] else [x, *ids[::-1], y]

    split = (pieces[fe] > 1).any(axis=1)
    out = [f[~split]]
    new = []
    for face, edges in zip(f[split].tolist(), fe[split].tolist(), strict=True):
        cuts = [pieces[q] > 1 for q in edges]
        if sum(cuts) == 1:  # fan from the corner opposite the cut edge
            r = cuts.index(True)
            a, b, c = face[r], face[(r + 1) % 3], face[(r + 2) % 3]
            ps = chain(a, b, edges[r])
            new += [(ps[i], ps[i + 1], c) for i in range(len(ps) - 1)]
            continue
        if sum(cuts) == 3:  # _split_long cuts those in four first
            raise ValueError("a face with three long edges reached the ladder split")
        r = (cuts.index(False) + 1) % 3  # the uncut edge becomes ca
        a, b, c = face[r], face[(r + 1) % 3], face[(r + 2) % 3]
        ab = chain(a, b, edges[r])  # a .. b
        cb = chain(c, b, edges[(r + 1) % 3])[:-1]  # c .. (before b)
        i = j = 0
        while i < len(ab) - 1 or j < len(cb) - 1:
            if i == len(ab) - 1:
                go_a = False
            elif j == len(cb) - 1:
                go_a = True
            else:
                go_a = np.sum((v[ab[i + 1]] - v[cb[j]]) ** 2) <= np.sum(
                    (v[ab[i]] - v[cb[j + 1]]) ** 2
                )
            if go_a:
                new.append((ab[i], ab[i + 1], cb[j]))
                i += 1
            else:
                new.append((ab[i], cb[j + 1], cb[j]))
                j += 1
    out.append(np.asarray(new, dtype=np.int64).reshape(-1, 3))
    return v, np.concatenate(out)
