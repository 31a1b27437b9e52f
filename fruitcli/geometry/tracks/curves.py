"""The track curves of make-tracks: the grid's plane sections of the reduced surface's
upward-facing part above the split plane (mm)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fruitcli.errors import GeometryError
from fruitcli.geometry.tracks import sections

# a face takes part in the track curves when its normal's z component exceeds this
UP_NZ_MIN = 0.05
# pieces of section curves shorter than this many track radii are not carved
MIN_PIECE_RADII = 4.0
# gaps in a track curve's upward-facing part shorter than this many track radii are bridged
MAX_GAP_RADII = 6.0
# track curves keep this many track radii above the split plane (no tube cuts the cap)
SPLIT_CLEARANCE_RADII = 2.0


def planes(lo: float, hi: float, spacing: float, origin: float | None) -> dict[int, float]:
    """Plane index -> coordinate for the planes origin + k * spacing inside (lo, hi)."""
    if origin is None:
        n = int(np.floor((hi - lo) / spacing))
        origin = 0.5 * (lo + hi) - 0.5 * n * spacing
    k0, k1 = int(np.ceil((lo - origin) / spacing)), int(np.floor((hi - origin) / spacing))
    return {k: origin + k * spacing for k in range(k0, k1 + 1)}


def upward_nz(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Per face, the smaller z component of its unit normal and of the area-weighted mean
    normal of the faces sharing a vertex with it.

    A level-set wall is a sawtooth of facets tilted alternately up and down by a few
    degrees; face by face about half of a vertical wall looks upward-facing, and bridging
    the gaps between those faces would run tracks down the wall. The neighbourhood mean
    cancels the sawtooth; taking the smaller value only ever drops faces from the mask.
    """
    tri = vertices[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    vn = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(vn, faces[:, k], fn)
    out = []
    for n in (fn, vn[faces].sum(axis=1)):
        out.append(n[:, 2] / np.maximum(np.linalg.norm(n, axis=1), 1e-300))
    return np.minimum(*out)


def track_curves(
    sv: np.ndarray,
    sf: np.ndarray,
    split: float,
    spacing_mm: tuple[float, float],
    origin_mm: Sequence[float] | None,
    track_radius_mm: float,
    src: str,
) -> tuple[dict, dict, dict[int, float], dict[int, float]]:
    """(x pieces, y pieces, x planes, y planes) of the surface (sv, sf) above z = `split`:
    per plane index, the section pieces (`sections.Piece`) to carve, on the planes x =
    const and y = const spaced `spacing_mm` (x, y) from `origin_mm` (None: centred)."""
    tri = sv[sf]
    up = (upward_nz(sv, sf) > UP_NZ_MIN) & (
        tri[:, :, 2].min(axis=1) > split + SPLIT_CLEARANCE_RADII * track_radius_mm
    )
    if not up.any():
        raise GeometryError(f"{src}: no upward-facing surface above z = {split:.2f} mm")
    upv = sv[np.unique(sf[up])]
    ox, oy = (None, None) if origin_mm is None else (float(origin_mm[0]), float(origin_mm[1]))
    x_planes = planes(upv[:, 0].min(), upv[:, 0].max(), spacing_mm[0], ox)
    y_planes = planes(upv[:, 1].min(), upv[:, 1].max(), spacing_mm[1], oy)
    min_len = MIN_PIECE_RADII * track_radius_mm
    max_gap = MAX_GAP_RADII * track_radius_mm
    below = tri[:, :, 2].max(axis=1) < split  # sections stay on the top half

    def cut(axis: int, at: dict[int, float]) -> dict:
        out = {}
        for k, value in at.items():
            ps = [
                q
                for p in sections.section_pieces(sv, sf, axis, value, ~below)
                for q in sections.masked_runs(p, up[p.faces], max_gap, min_len)
            ]
            if ps:
                out[k] = ps
        return out

    return cut(0, x_planes), cut(1, y_planes), x_planes, y_planes
