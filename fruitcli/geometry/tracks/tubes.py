"""Tubes swept along polylines (the yarn tracks), as closed triangle meshes in mm.

Resampled at about `step_mm`, rotation-minimising frames (double reflection), rings of
`ring` vertices, flat end caps. Closed loops are split into two overlapping open tubes.
"""

from __future__ import annotations

import numpy as np

TUBE_STEP_MM = 1.0
TUBE_RING = 12


def resample(points: np.ndarray, step_mm: float) -> np.ndarray:
    """Points (k, 3) resampled to about `step_mm` along the polyline (ends kept)."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    keep = np.r_[True, seg > 0]
    points, s = points[keep], np.r_[0.0, np.cumsum(seg[seg > 0])]
    n = max(2, int(np.ceil(s[-1] / step_mm)) + 1)
    t = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(t, s, points[:, k]) for k in range(3)], axis=1)


def rotation_minimising_frames(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangents (k, 3) and normals (k, 3) along a polyline (Wang et al., 2008)."""
    tan = np.gradient(points, axis=0)
    tan /= np.linalg.norm(tan, axis=1, keepdims=True)
    helper = np.eye(3)[np.argmin(np.abs(tan[0]))]
    r = np.cross(tan[0], helper)
    r /= np.linalg.norm(r)
    normals = np.zeros_like(points)
    normals[0] = r
    for i in range(len(points) - 1):
        v1 = points[i + 1] - points[i]
        c1 = v1 @ v1
        if c1 == 0:
            normals[i + 1] = normals[i]
            continue
        r_l = normals[i] - (2.0 / c1) * (v1 @ normals[i]) * v1
        t_l = tan[i] - (2.0 / c1) * (v1 @ tan[i]) * v1
        v2 = tan[i + 1] - t_l
        c2 = v2 @ v2
        n = r_l - (2.0 / c2) * (v2 @ r_l) * v2 if c2 > 0 else r_l
        n -= (n @ tan[i + 1]) * tan[i + 1]
        normals[i + 1] = n / np.linalg.norm(n)
    return tan, normals


def tube_arrays(
    points: np.ndarray, radius_mm: float, step_mm: float = TUBE_STEP_MM, ring: int = TUBE_RING
) -> tuple[np.ndarray, np.ndarray]:
    """A closed, outward-oriented tube along an open polyline: vertices (n, 3), faces (m, 3)."""
    p = resample(np.asarray(points, dtype=float), step_mm)
    tan, nrm = rotation_minimising_frames(p)
    bin_ = np.cross(tan, nrm)
    phi = 2.0 * np.pi * np.arange(ring) / ring
    rings = p[:, None, :] + radius_mm * (
        np.cos(phi)[None, :, None] * nrm[:, None, :] + np.sin(phi)[None, :, None] * bin_[:, None, :]
    )
    k = len(p)
    verts = np.concatenate([rings.reshape(-1, 3), p[[0, -1]]])
    r = np.arange(k - 1)[:, None]
    j = np.arange(ring)[None, :]
    j1 = (j + 1) % ring
    a, b = r * ring + j, r * ring + j1
    c, d = a + ring, b + ring
    side = np.concatenate([np.stack([a, b, c], -1), np.stack([b, d, c], -1)], axis=1)
    c0, c1 = k * ring, k * ring + 1
    js = np.arange(ring)
    cap0 = np.c_[np.full(ring, c0), (js + 1) % ring, js]
    last = (k - 1) * ring
    cap1 = np.c_[np.full(ring, c1), last + js, last + (js + 1) % ring]
    faces = np.concatenate([side.reshape(-1, 3), cap0, cap1]).astype(np.int64)
    tri = verts[faces]
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()
    if vol < 0:
        faces = faces[:, ::-1].copy()
    return verts, faces


def track_polylines(points: np.ndarray, closed: bool) -> list[np.ndarray]:
    """Open polylines to sweep: the piece itself, or a closed loop as two overlapping halves."""
    if not closed:
        return [points]
    k = len(points) - 1  # last point repeats the first
    half, lap = k // 2, max(1, k // 10)
    loop = np.concatenate([points[:-1], points[:-1]])
    return [loop[: half + lap + 1], loop[half : k + lap + 1]]
