"""Taxels: crossings of the x = const and y = const track curves on the reduced surface.

A taxel has grid indices (i along x, j along y), a position on the surface (mm) and the
outward unit normal there (vertex normals interpolated in its face).
"""

from __future__ import annotations

import numpy as np

from fruitcli.geometry.tracks.sections import Piece


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (n, 3) of an outward-oriented mesh."""
    tri = vertices[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    vn = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(vn, faces[:, k], fn)
    norm = np.linalg.norm(vn, axis=1, keepdims=True)
    return vn / np.where(norm > 0, norm, 1.0)


def piece_crossings(
    piece: Piece, axis: int, values: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where a piece crosses the planes `coordinate[axis] = values[l]`.

    Returns (plane index l (c,), points (c, 3), faces (c,)).
    """
    a, b = piece.points[:-1], piece.points[1:]
    ca, cb = a[:, axis][:, None], b[:, axis][:, None]
    v = np.asarray(values, dtype=float)[None, :]
    hit = (ca >= v) != (cb >= v)
    seg, lidx = np.nonzero(hit)
    t = (v[0, lidx] - ca[seg, 0]) / (cb[seg, 0] - ca[seg, 0])
    pts = a[seg] + (b[seg] - a[seg]) * t[:, None]
    pts[:, axis] = v[0, lidx]
    return lidx, pts, piece.faces[seg]


def grid_crossings(
    pieces_by_plane: dict[int, list[Piece]],
    axis_other: int,
    values_other: np.ndarray,
    offset_other: int,
) -> dict:
    """{(plane index, other plane index): (point, face)}, the top-most crossing for each."""
    out: dict[tuple[int, int], tuple[np.ndarray, int]] = {}
    for k, pieces in pieces_by_plane.items():
        for piece in pieces:
            lidx, pts, fcs = piece_crossings(piece, axis_other, values_other)
            for l_, p, f in zip(lidx.tolist(), pts, fcs.tolist(), strict=True):
                key = (k, l_ + offset_other)
                if key not in out or p[2] > out[key][0][2]:
                    out[key] = (p, f)
    return out


def find_taxels(
    x_pieces: dict[int, list[Piece]],
    y_pieces: dict[int, list[Piece]],
    x_planes: dict[int, float],
    y_planes: dict[int, float],
    vertices: np.ndarray,
    faces: np.ndarray,
) -> dict:
    """Crossings present on both an x-curve and a y-curve.

    Returns {"k": (T,) x-plane index, "l": (T,) y-plane index, "xyz": (T, 3) mm,
    "normals": (T, 3), "face": (T,), "mismatch_mm": largest x/y-curve disagreement}.
    """
    kx = sorted(x_planes)
    ly = sorted(y_planes)
    xs = np.array([x_planes[k] for k in kx])
    ys = np.array([y_planes[l_] for l_ in ly])
    from_x = grid_crossings(x_pieces, 1, ys, ly[0] if ly else 0)
    from_y = {
        (k, l_): v for (l_, k), v in grid_crossings(y_pieces, 0, xs, kx[0] if kx else 0).items()
    }
    keys = sorted(set(from_x) & set(from_y))
    if not keys:
        return {
            "k": np.zeros(0, int),
            "l": np.zeros(0, int),
            "xyz": np.zeros((0, 3)),
            "normals": np.zeros((0, 3)),
            "face": np.zeros(0, int),
            "mismatch_mm": 0.0,
        }
    xyz = np.array([from_x[key][0] for key in keys])
    other = np.array([from_y[key][0] for key in keys])
    face = np.array([from_x[key][1] for key in keys])
    normals = interpolated_normals(vertices, faces, face, xyz)
    return {
        "k": np.array([key[0] for key in keys]),
        "l": np.array([key[1] for key in keys]),
        "xyz": xyz,
        "normals": normals,
        "face": face,
        "mismatch_mm": float(np.linalg.norm(xyz - other, axis=1).max()),
    }


def interpolated_normals(
    vertices: np.ndarray, faces: np.ndarray, face: np.ndarray, points: np.ndarray
) -> np.ndarray:
    """Unit normals (n, 3) at points on given faces: vertex normals mixed barycentrically."""
    vn = vertex_normals(vertices, faces)
    tri = vertices[faces[face]]
    v0, v1, v2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], points - tri[:, 0]
    d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
    d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
    den = d00 * d11 - d01 * d01
    den = np.where(den == 0, 1.0, den)
    w1 = (d11 * d20 - d01 * d21) / den
    w2 = (d00 * d21 - d01 * d20) / den
    w0 = 1.0 - w1 - w2
    n = (
        w0[:, None] * vn[faces[face, 0]]
        + w1[:, None] * vn[faces[face, 1]]
        + w2[:, None] * vn[faces[face, 2]]
    )
    return n / np.linalg.norm(n, axis=1, keepdims=True)
