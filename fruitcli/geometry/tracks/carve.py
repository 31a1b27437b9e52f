"""Carving the yarn tracks: tubes along the track curves subtracted from the casting
piece above the split plane, and the slivers that tubes along a sharp edge cut off
dropped (mm, mm^3)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from fruitcli.errors import GeometryError
from fruitcli.geometry.mesh import export, load
from fruitcli.geometry.tracks import reduce, tubes

if TYPE_CHECKING:
    import manifold3d

# the tracked piece may lose at most this fraction of its volume to the tubes
MAX_TRACK_VOLUME_FRACTION = 0.25
# bodies cut off by the tubes (along a sharp edge) are dropped below this fraction of the
# piece's volume, in total; larger ones make the carving fail
MAX_SLIVER_VOLUME_FRACTION = 1e-3


def change_tracks(opt: dict) -> str:
    """What to change when the tracks cut the piece apart (`opt`: the options' names)."""
    return (
        f"try a smaller {opt['track_radius_mm']}, or move the grid lines ({opt['origin_mm']}, "
        f"{opt['spacing_x_mm']}, {opt['spacing_y_mm']})"
    )


def drop_slivers(piece: manifold3d.Manifold, top_volume: float) -> tuple[Any, list[float]]:
    """Drop the small bodies that tubes running along a sharp edge cut off the piece.

    Returns (the piece without them, [their volumes in mm^3]).
    """
    import manifold3d

    if piece.is_empty() or piece.status() != manifold3d.Error.NoError:
        return piece, []
    parts = sorted(piece.decompose(), key=lambda m: -m.volume())
    small = [float(p.volume()) for p in parts[1:]]
    if not small or sum(small) >= MAX_SLIVER_VOLUME_FRACTION * top_volume:
        return piece, []
    return parts[0], small


def drop_edge_slivers(
    vertices: np.ndarray, faces: np.ndarray, top_volume: float
) -> tuple[np.ndarray, list[float]]:
    """Faces of the largest edge-connected shell, and the volumes (mm^3) of the others.

    manifold3d counts shells touching at a vertex as one body, and welding for a float32
    STL can remove the zero-volume fin that joined them; an STL reader sees separate bodies.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, edge_id = np.unique(e[:, 0] * len(vertices) + e[:, 1], return_inverse=True)
    owner = np.tile(np.arange(len(faces)), 3)
    graph = coo_matrix(
        (np.ones(len(owner)), (owner, edge_id.ravel() + len(faces))),
        shape=(len(faces) + edge_id.max() + 1,) * 2,
    )
    n, labels = connected_components(graph, directed=False)
    labels = labels[: len(faces)]
    if len(np.unique(labels)) == 1:
        return faces, []
    tri = vertices[faces]
    six_vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
    vol = np.bincount(labels, six_vol, minlength=n) / 6.0
    big = int(np.argmax(vol))
    others = [float(v) for k, v in enumerate(vol) if k != big and np.any(labels == k)]
    if sum(abs(v) for v in others) >= MAX_SLIVER_VOLUME_FRACTION * top_volume:
        return faces, []
    return faces[labels == big], others


@dataclass
class Carved:
    """The carved piece: the track curves (points (n, 3) mm, closed or not, and (axis,
    grid index) each), their tube meshes (vertices, faces), the tracked piece (a
    manifold3d.Manifold) and its welded float32 arrays (kv, kf), and the slivers dropped
    (mm^3)."""

    curves: list
    closed: list
    curve_ids: list
    tube_meshes: list
    tracked: Any  # manifold3d.Manifold
    kv: np.ndarray
    kf: np.ndarray
    slivers: list


def carve(
    top: manifold3d.Manifold,
    x_pieces: dict,
    y_pieces: dict,
    k0: int,
    l0: int,
    radius_mm: float,
    opt: dict,
    src: str,
) -> Carved:
    """Subtract tubes of `radius_mm` along every piece of `x_pieces` and `y_pieces` (plane
    index -> pieces; indices counted from k0 and l0) from the piece `top`; GeometryError
    when a tube or the result is not a valid solid, or the piece falls apart."""
    import manifold3d

    curves = [p.points for d in (x_pieces, y_pieces) for k in sorted(d) for p in d[k]]
    closed = [p.closed for d in (x_pieces, y_pieces) for k in sorted(d) for p in d[k]]
    # each curve's axis (x: a plane x = const, index i; y: y = const, index j)
    curve_ids = [
        (axis, k - k_min)
        for axis, d, k_min in (("x", x_pieces, k0), ("y", y_pieces, l0))
        for k in sorted(d)
        for _ in d[k]
    ]
    tube_meshes = []
    for pts, cl in zip(curves, closed, strict=True):
        for line in tubes.track_polylines(pts, cl):
            tube_meshes.append(tubes.tube_arrays(line, radius_mm))
    tube_manifolds = [load.to_manifold(v, f) for v, f in tube_meshes]
    bad = [m.status().name for m in tube_manifolds if m.status() != manifold3d.Error.NoError]
    if bad:
        raise GeometryError(
            f"{src}: {len(bad)} track tube(s) are not valid solids ({bad[0]}); "
            f"try a smaller {opt['track_radius_mm']}"
        )
    tracked = manifold3d.Manifold.batch_boolean([top, *tube_manifolds], manifold3d.OpType.Subtract)
    tracked, slivers = drop_slivers(tracked, top.volume())
    lost = 1.0 - tracked.volume() / top.volume()
    n_tracked = len(tracked.decompose()) if not tracked.is_empty() else 0
    if (
        tracked.status() != manifold3d.Error.NoError
        or n_tracked != 1
        or not 0 < lost < MAX_TRACK_VOLUME_FRACTION
    ):
        raise GeometryError(
            f"{src}: carving the tracks gave an invalid piece ({n_tracked} "
            f"bodies, genus {tracked.genus()}, {100 * lost:.1f} % removed); "
            f"{change_tracks(opt)}"
        )
    kv, kf = export.weld_float32(*reduce.manifold_arrays(tracked))
    kf, more = drop_edge_slivers(kv, kf, top.volume())
    return Carved(curves, closed, curve_ids, tube_meshes, tracked, kv, kf, slivers + more)
