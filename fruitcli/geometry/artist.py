"""The default artist mesh: a procedural, deterministic organic "Fruit" (paper Fig. 6a).

A body swept along a planar centreline: a straight trunk along +y, a 90 degree bend and
a tapering tip reaching out towards -x. Superelliptic cross-sections, a few fixed
sinusoidal bumps, a soft-clamped flat base at z = BASE_Z_MM. A smooth height correction
puts the top surface at the paper's rest truth heights (data/paper/paper_rest_truth.csv),
so the paper's measurement protocol can be replayed at the paper's own positions.
All lengths in mm; no random numbers.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.geometry.mesh.columns import top_z

if TYPE_CHECKING:
    import trimesh

# centreline: trunk from (15, -66) along +y to (15, 5); arc of radius 45 about (-30, 5)
# turning left by 90 degrees to (-30, 50); tip straight along -x to (-95, 50)
TRUNK_START_MM = (15.0, -66.0)
TRUNK_LENGTH_MM = 71.0
BEND_RADIUS_MM = 45.0
TIP_LENGTH_MM = 65.0
BASE_Z_MM = -31.0
BASE_SOFTNESS_MM = 2.5
START_CAP_MM = 32.0
END_CAP_MM = 10.0
SUPERELLIPSE_P = 2.6

# arclength knots (mm) -> half-width a, half-height b, centre height zc (mm)
_KNOT_S = np.array([0.0, 95.0, 125.0, 150.0, 185.0, 210.0])
_KNOT_A = np.array([34.0, 34.0, 19.0, 13.0, 10.0, 8.0])
_KNOT_B = np.array([18.0, 18.0, 12.0, 10.0, 7.0, 6.0])
_KNOT_ZC = np.array([-15.0, -14.0, -8.0, -6.0, -10.0, -12.0])

# bumps: (amplitude, waves along s per 100 mm, waves around, phase)
_BUMPS = (
    (0.030, 2.3, 3.0, 0.4),
    (0.022, 3.7, 5.0, 1.9),
    (0.016, 5.9, 2.0, 4.1),
    (0.012, 8.3, 7.0, 2.7),
)

N_ALONG = 420
N_AROUND = 160
CORRECTION_SIGMA_MM = 9.0
CORRECTION_ITERATIONS = 3

# the paper's 29 rest sample points (x, y, z) in mm, copied from paper_rest_truth.csv so the
# generator does not depend on the data folder being present
PAPER_REST_TRUTH_MM = np.array(
    [
        [-77.392241, 53.103448, -4.794208],
        [-60.517241, 53.103448, -1.543040],
        [-43.642241, 53.103448, 4.221074],
        [-26.767241, 40.881226, 0.589280],
        [-26.767241, 53.103448, 3.174063],
        [-9.892241, -44.674330, -7.681267],
        [-9.892241, -32.452107, -3.454732],
        [-9.892241, -20.229885, 2.693112],
        [-9.892241, -8.007663, 6.802435],
        [-9.892241, 4.214559, 7.791869],
        [-9.892241, 16.436782, 5.544413],
        [-9.892241, 28.659004, 9.548597],
        [-9.892241, 40.881226, 7.888070],
        [6.982759, -44.674330, -9.846026],
        [6.982759, -32.452107, -8.479984],
        [6.982759, -20.229885, -5.513335],
        [6.982759, -8.007663, -3.003260],
        [6.982759, 4.214559, 0.223691],
        [6.982759, 16.436782, 2.437189],
        [6.982759, 28.659004, 5.405156],
        [23.857759, -44.674330, -4.741322],
        [23.857759, -32.452107, -2.739506],
        [23.857759, -20.229885, -1.404965],
        [23.857759, -8.007663, -4.840598],
        [23.857759, 4.214559, -6.390879],
        [23.857759, 16.436782, -2.152111],
        [40.732759, -44.674330, 0.338342],
        [40.732759, -32.452107, 4.629276],
        [40.732759, -20.229885, 5.298665],
    ]
)

# three ellipsoidal pneumatic chambers inside the body (mm)
FRUIT_CHAMBERS = [
    {"name": "c1", "center_mm": [15.0, -36.0, -20.5], "radii_mm": [13.0, 10.0, 4.0]},
    {"name": "c2", "center_mm": [12.0, -4.0, -20.5], "radii_mm": [13.0, 10.0, 4.0]},
    {"name": "c3", "center_mm": [3.0, 30.0, -14.0], "radii_mm": [9.0, 7.0, 4.0]},
]


def centreline(s_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centreline points (n, 2) and unit tangents (n, 2) at arclengths `s_mm` (n,)."""
    s = np.asarray(s_mm, dtype=float)
    x0, y0 = TRUNK_START_MM
    arc_len = 0.5 * np.pi * BEND_RADIUS_MM
    pts = np.zeros((len(s), 2))
    tan = np.zeros((len(s), 2))
    trunk = s <= TRUNK_LENGTH_MM
    pts[trunk] = np.c_[np.full(trunk.sum(), x0), y0 + s[trunk]]
    tan[trunk] = (0.0, 1.0)
    bend = (s > TRUNK_LENGTH_MM) & (s <= TRUNK_LENGTH_MM + arc_len)
    phi = (s[bend] - TRUNK_LENGTH_MM) / BEND_RADIUS_MM
    cx, cy = x0 - BEND_RADIUS_MM, y0 + TRUNK_LENGTH_MM
    pts[bend] = np.c_[cx + BEND_RADIUS_MM * np.cos(phi), cy + BEND_RADIUS_MM * np.sin(phi)]
    tan[bend] = np.c_[-np.sin(phi), np.cos(phi)]
    tip = s > TRUNK_LENGTH_MM + arc_len
    d = s[tip] - TRUNK_LENGTH_MM - arc_len
    pts[tip] = np.c_[cx - d, np.full(tip.sum(), cy + BEND_RADIUS_MM)]
    tan[tip] = (-1.0, 0.0)
    return pts, tan


def _smooth_interp(s: np.ndarray, knots: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Piecewise smoothstep interpolation between knots (C1, monotone between knots)."""
    k = np.clip(np.searchsorted(knots, s, side="right") - 1, 0, len(knots) - 2)
    t = np.clip((s - knots[k]) / (knots[k + 1] - knots[k]), 0.0, 1.0)
    t = t * t * (3.0 - 2.0 * t)
    return values[k] + (values[k + 1] - values[k]) * t


def _signed_pow(x: np.ndarray, e: float) -> np.ndarray:
    return np.sign(x) * np.abs(x) ** e


def _body_vertices(n_along: int, n_around: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Ring vertices (n_along, n_around, 3), the up-ness weight per vertex, total length."""
    length = TRUNK_LENGTH_MM + 0.5 * np.pi * BEND_RADIUS_MM + TIP_LENGTH_MM
    u = (np.arange(1, n_along + 1)) / (n_along + 1)
    s = 0.5 * length * (1.0 - np.cos(np.pi * u))  # dense near both ends
    theta = 2.0 * np.pi * np.arange(n_around) / n_around
    pts, tan = centreline(s)
    normal = np.c_[-tan[:, 1], tan[:, 0]]  # left of the tangent
    cap0 = np.sqrt(1.0 - (1.0 - np.minimum(s / START_CAP_MM, 1.0)) ** 2)
    cap1 = np.sqrt(1.0 - (1.0 - np.minimum((length - s) / END_CAP_MM, 1.0)) ** 2)
    cap = cap0 * cap1
    a = _smooth_interp(s, _KNOT_S, _KNOT_A) * cap
    b = _smooth_interp(s, _KNOT_S, _KNOT_B) * np.sqrt(cap)
    zc = _smooth_interp(s, _KNOT_S, _KNOT_ZC)
    e = 2.0 / SUPERELLIPSE_P
    cs, sn = _signed_pow(np.cos(theta), e), _signed_pow(np.sin(theta), e)
    bump = np.ones((n_along, n_around))
    pole_fade = np.sin(np.pi * u)[:, None] ** 0.5
    for amp, waves, around, phase in _BUMPS:
        bump += (
            amp
            * pole_fade
            * np.sin(2 * np.pi * waves * s[:, None] / 100.0 + phase)
            * np.cos(around * theta[None, :] + 0.7 * phase)
        )
    lateral = a[:, None] * cs[None, :] * bump
    xy = pts[:, None, :] + lateral[:, :, None] * normal[:, None, :]
    z = zc[:, None] + b[:, None] * sn[None, :] * bump
    z = BASE_Z_MM + BASE_SOFTNESS_MM * np.logaddexp(0.0, (z - BASE_Z_MM) / BASE_SOFTNESS_MM)
    up = np.clip((np.sin(theta) - 0.15) / 0.55, 0.0, 1.0)
    # no lift near the poles, where tiny rings would fold
    up = (up * up * (3 - 2 * up))[None, :] * (cap**2)[:, None]
    verts = np.concatenate([xy, z[:, :, None]], axis=2)
    return verts, up, length


def _ring_faces(n_along: int, n_around: int) -> np.ndarray:
    """Faces of a closed tube of rings plus two pole fans (poles at the last two indices)."""
    r = np.arange(n_along - 1)[:, None]
    k = np.arange(n_around)[None, :]
    k1 = (k + 1) % n_around
    a, b = r * n_around + k, r * n_around + k1
    c, d = (r + 1) * n_around + k, (r + 1) * n_around + k1
    quads = np.concatenate([np.stack([a, c, b], -1), np.stack([b, c, d], -1)], axis=1)
    p0, p1 = n_along * n_around, n_along * n_around + 1
    ks = np.arange(n_around)
    fan0 = np.c_[np.full(n_around, p0), ks, (ks + 1) % n_around]
    last = (n_along - 1) * n_around
    fan1 = np.c_[np.full(n_around, p1), last + (ks + 1) % n_around, last + ks]
    return np.concatenate([quads.reshape(-1, 3), fan0, fan1]).astype(np.int64)


def _gaussian_field(centers: np.ndarray, weights: np.ndarray, xy: np.ndarray) -> np.ndarray:
    d2 = ((xy[:, None, :] - centers[None, :, :]) ** 2).sum(-1)
    return np.exp(-0.5 * d2 / CORRECTION_SIGMA_MM**2) @ weights


def fruit_arrays(
    n_along: int = N_ALONG, n_around: int = N_AROUND, match_truth: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) mm and outward-oriented faces (m, 3) of the Fruit.

    With `match_truth`, a smooth Gaussian height field on the upper side moves the top
    surface onto the paper's rest truth heights at the 29 sample positions.
    """
    ring, up, _ = _body_vertices(n_along, n_around)
    faces = _ring_faces(n_along, n_around)

    def assemble(rv: np.ndarray):
        flat = rv.reshape(-1, 3)
        ends = np.array([rv[0].mean(axis=0), rv[-1].mean(axis=0)])
        return np.concatenate([flat, ends])

    verts = assemble(ring)
    if match_truth:
        truth = PAPER_REST_TRUTH_MM
        centers = truth[:, :2]
        gram = np.exp(
            -0.5 * ((centers[:, None] - centers[None]) ** 2).sum(-1) / CORRECTION_SIGMA_MM**2
        )
        lift = np.zeros(ring.shape[:2])
        ring_xy = ring[:, :, :2].reshape(-1, 2)
        for _ in range(CORRECTION_ITERATIONS):
            residual = truth[:, 2] - top_z(verts, faces, centers)
            w = np.linalg.solve(gram + 1e-6 * np.eye(len(gram)), np.nan_to_num(residual))
            lift = lift + _gaussian_field(centers, w, ring_xy).reshape(lift.shape)
            moved = ring.copy()
            moved[:, :, 2] += up * lift
            verts = assemble(moved)
    # orientation: outward normals give a positive signed volume
    tri = verts[faces]
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0
    if vol < 0:
        faces = faces[:, ::-1].copy()
    return verts, faces


def make_fruit_artist(n_along: int = N_ALONG, n_around: int = N_AROUND) -> trimesh.Trimesh:
    """The default artist mesh as a closed trimesh.Trimesh in mm (>= 100,000 triangles)."""
    import trimesh

    verts, faces = fruit_arrays(n_along, n_around)
    return trimesh.Trimesh(verts, faces, process=False)


def write_artist(path: str | Path, n_along: int = N_ALONG, n_around: int = N_AROUND) -> dict:
    """Write the default Fruit to `path` (.stl, .obj or .ply) atomically; returns a summary."""
    from fruitcli.errors import GeometryError
    from fruitcli.fsutil import atomic_path

    path = Path(path)
    kind = path.suffix.lower().lstrip(".")
    if kind not in ("stl", "obj", "ply"):
        raise GeometryError(
            f"{path}: unknown mesh format '{path.suffix}' (expected .stl, .obj or .ply)"
        )
    mesh = make_fruit_artist(n_along, n_around)
    with atomic_path(path) as tmp:
        mesh.export(tmp, file_type=kind)
    lo, hi = mesh.bounds
    return {
        "path": str(path),
        "triangles": int(len(mesh.faces)),
        "vertices": int(len(mesh.vertices)),
        "bounds_mm": [lo.tolist(), hi.tolist()],
        "volume_mm3": float(mesh.volume),
    }
