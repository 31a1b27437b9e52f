"""The skin's forward model: raw CDC counts of every taxel for an indenter and a FEM state.

Units: mm, counts. The touch response's parameters (footprint width per indenter, counts
at contact, gap decay, noise, taxel gain spread) are a scene's ``[skin]`` table
(`SkinParams`); its defaults are declared once, in the scene schema (`fruitcli.scene`),
and named here (``CONTACT_COUNTS`` ...). Each parameter, its default and its
source (none is fitted to the paper's Table I; `fruit study bench` shows how the bench's
rows depend on the assumed ones):

- ``THRESHOLD_COUNTS`` = 20: the paper's touch threshold, "very light touch or even
  pre-touch" (Sec. V-A).
- ``CONTACT_COUNTS`` = 60: activation of a taxel right under an indenter at contact.
  Assumption: three times the threshold, so the threshold is crossed just before contact
  (pre-touch, Sec. V-A). ``[skin].contact_counts``.
- ``GAP_DECAY_MM`` = 2: activation falls as exp(-gap / 2 mm) with the indenter's gap to
  the surface. Assumption: the fringing field reaches about one cover thickness
  (``[tracks].cover_mm`` = 2 mm) beyond the electrodes (Sec. III-C, Fig. 5). With 60
  counts at contact, the threshold is crossed at a gap of 2 ln 3 = 2.2 mm.
  ``[skin].gap_decay_mm``.
- ``[skin].height_as_distance`` = 1, ``height_as_gap`` = 0: how a crossing's height
  difference h from the contact point (along z, the bench's approach) enters. The
  Gaussian's squared distance is r^2 + height_as_distance h^2 (r the offset across z), and
  the gap gap + height_as_gap |h|: by default the 3D distance; ``fruit calibrate`` fits
  both (an electrostatic board's crossings see h as gap, not as distance).
- ``[skin].widening_per_mm`` = 0: the footprint's width grows with the gap, sigma (1 + w
  g), g the gap (0 for a press) plus ``height_as_gap`` |h|. By default it does not; ``fruit
  calibrate`` fits it (an electrostatic crossing's field spreads as it reaches farther).
- ``FIELD_SIGMA_MM`` = 6: the lateral reach of one crossing, a Gaussian in the 3D
  distance from the contact point to the (deformed) taxel. Assumption: half the 12 mm
  pitch, so a quarter-taxel offset activates more than one taxel, as the paper's bench
  protocol requires (Sec. V-B).
- ``INDENTER_RADIUS_MM``: small rubber tip 1.5 mm, medium Allen key 4 mm (Fig. 15 (a),
  (b): the Allen key is the wider one); the footprint is sigma = hypot(FIELD_SIGMA_MM, r):
  6.18 mm small, 7.21 mm medium, ``[skin].footprint_sigma_mm`` per indenter. This width
  sets the bench's error more than any other parameter (`fruit study bench`).
- Taxel gain: activation times a per-taxel gain, 1 by default; ``[skin].gain_spread`` =
  s draws gains uniformly in 1 +- s (seeded). Assumption: a uniform skin.
  ``[skin].taxel_gain`` = a CSV (id, gain), e.g. `fruit calibrate`'s gains.csv, gives
  measured gains instead.
- ``BASELINE_COUNTS`` = 500 +- 30 (seeded per taxel): per-taxel baselines C0. Only
  differences matter; any level works (the FT5316 reports 16-bit counts).
- Noise: Gaussian, per-taxel std drawn uniformly in [0.5, 1.85] counts (seeded), so the
  measured std of the integer counts peaks near the paper's 1.9 counts (Fig. 10);
  ``[skin].noise_std_counts``: that range [lo, hi], or one std for every taxel.
- Deformation baseline shift: ``gain * fab * strain``, strain = the area-weighted
  in-plane Green strain norm of the FEM surface within ``CROSSING_RADIUS_MM`` = 4 mm of
  the crossing (assumption: the yarns are sewn into the surface, so the crossing feels
  the surface's stretch; a surface measure does not depend on how many tets the
  thickness has). The gain is
  calibrated by `calibrate_strain_gain`: the flat 80 x 80 x 3 mm pad with 4 x 4 taxels
  bent 180 deg over its 48 mm active length (radius 48/pi mm) shifts its most strained
  taxel by 10 counts (Fig. 9). ``fab`` is a per-taxel fabrication factor: 1 for a
  well-made crossing; a seeded ``DEFECT_PROBABILITY`` = 5 % of crossings "deform more
  than intended" (the paper's explanation of its tip outliers, Sec. V-A) with a factor
  drawn uniformly in [1.5, 2.5] (assumption: enough to turn the 5-count typical shift
  into the 10-16 counts of the outliers of Fig. 11). The shift is positive (towards a
  false touch, the worst case). The breathing animation's shifts are an output of the
  model, reported by `fruit` (sensitivity.json), to compare with Fig. 11 (5 mean, 16 max).
- Counts are rounded to integers and clipped to the board's 16-bit range 0 .. 65535.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.geometry.state_mesh import StateMesh
from fruitcli.scene import SCHEMA, default_scene

if TYPE_CHECKING:
    from fruitcli.scene import SkinSection

_SKIN = SCHEMA["skin"]  # the [skin] keys, whose defaults the scene schema declares
THRESHOLD_COUNTS = 20.0
CONTACT_COUNTS = float(_SKIN["contact_counts"].default)
GAP_DECAY_MM = float(_SKIN["gap_decay_mm"].default)
FIELD_SIGMA_MM = 6.0
INDENTER_RADIUS_MM = {"small": 1.5, "medium": 4.0}
BASELINE_COUNTS = 500.0
BASELINE_SPREAD_COUNTS = 30.0
NOISE_STD_RANGE_COUNTS = tuple(_SKIN["noise_std_counts"].default)
DEFECT_PROBABILITY = 0.05  # share of crossings that deform more than intended
DEFECT_FACTOR_RANGE = (1.5, 2.5)
BEND_SHIFT_COUNTS = 10.0  # Fig. 9: 4 x 4 pad bent 180 deg
PAD_SIZE_MM = (80.0, 80.0, 3.0)
PAD_ACTIVE_MM = 48.0
PAD_PITCH_MM = 16.0
_DET_EPS = 1e-12  # a surface triangle whose metric det (mm^4) or area is below this is degenerate
CROSSING_RADIUS_MM = 4.0  # surface around a crossing whose stretch shifts its baseline
CROSSING_PLANE_MM = 1.0  # ... and how far off the crossing's tangent plane it may curve


GAIN_STREAM = 7  # gains are drawn from their own seeded stream: spread 0 changes nothing


def default_footprints_mm() -> dict[str, float]:
    """Footprint sigma per indenter (mm): hypot(FIELD_SIGMA_MM, indenter radius)."""
    return {k: float(np.hypot(FIELD_SIGMA_MM, r)) for k, r in INDENTER_RADIUS_MM.items()}


class StatesMesh(StateMesh, Protocol):
    """What the skin reads of the FEM states (`fruitcli.sensing.detection.locate.States`):
    the body surface's (`StateMesh`: the rest mesh in mm, its surface, a state's nodes),
    the displacements (S, N, 3) mm and each taxel's tet and barycentric weights."""

    @property
    def displacement_mm(self) -> np.ndarray: ...
    @property
    def taxel_tet(self) -> np.ndarray: ...
    @property
    def taxel_bary(self) -> np.ndarray: ...


@dataclass(frozen=True)
class SkinParams:
    """The touch response's parameters, a scene's [skin] table (mm, counts)."""

    footprint_sigma_mm: dict  # indenter name -> lateral Gaussian width (mm)
    contact_counts: float = CONTACT_COUNTS
    gap_decay_mm: float = GAP_DECAY_MM
    gain_spread: float = float(_SKIN["gain_spread"].default)  # gains uniform in 1 +- spread
    noise_std_counts: float | tuple = NOISE_STD_RANGE_COUNTS  # one std, or (lo, hi) per taxel
    taxel_gain: Path | None = _SKIN["taxel_gain"].default  # CSV (id, gain) of measured gains
    height_as_distance: float = 1.0  # weight of a crossing's height difference in d^2
    height_as_gap: float = 0.0  # share of it added to the gap
    widening_per_mm: float = 0.0  # the width's growth per mm of gap: sigma (1 + w g)

    @classmethod
    def from_table(cls, skin: SkinSection | None = None) -> SkinParams:
        """From a scene's [skin] (a `fruitcli.scene.SkinSection`; None: the defaults)."""
        skin = default_scene().skin if skin is None else skin
        feet = {**default_footprints_mm(), **(skin.footprint_sigma_mm or {})}
        noise = skin.noise_std_counts
        return cls(
            {k: float(v) for k, v in feet.items()},
            float(skin.contact_counts),
            float(skin.gap_decay_mm),
            float(skin.gain_spread),
            tuple(map(float, noise)) if isinstance(noise, (list, tuple)) else float(noise),
            skin.taxel_gain,
            float(skin.height_as_distance),
            float(skin.height_as_gap),
            float(skin.widening_per_mm),
        )


DEFAULT_PARAMS = SkinParams(default_footprints_mm())


@dataclass(frozen=True)
class Skin:
    """Per-taxel properties of one fabricated skin (seeded) and its touch response."""

    baseline_counts: np.ndarray  # (T,)
    noise_std_counts: np.ndarray  # (T,)
    fab: np.ndarray  # (T,) fabrication factor of the strain shift
    gain: np.ndarray | None = None  # (T,) activation gain, None: 1
    params: SkinParams = DEFAULT_PARAMS


def make_skin(
    n_taxels: int,
    seed: int = 0,
    params: SkinParams = DEFAULT_PARAMS,
    taxel_ids: np.ndarray | None = None,
) -> Skin:
    """Draw per-taxel baselines, noise std, fabrication factors and gains from `seed`;
    with ``params.taxel_gain`` the gains are read from it for `taxel_ids` (T,)."""
    rng = np.random.default_rng(seed)
    base = BASELINE_COUNTS + rng.uniform(-1, 1, n_taxels) * BASELINE_SPREAD_COUNTS
    noise = params.noise_std_counts
    lo, hi = noise if isinstance(noise, tuple) else NOISE_STD_RANGE_COUNTS
    std = rng.uniform(lo, hi, n_taxels)  # drawn in any case: the later draws stay the same
    if not isinstance(noise, tuple):
        std = np.full(n_taxels, noise)
    defect = rng.random(n_taxels) < DEFECT_PROBABILITY
    fab = np.where(defect, rng.uniform(*DEFECT_FACTOR_RANGE, n_taxels), 1.0)
    gain = None
    if params.gain_spread > 0:
        g = np.random.default_rng([seed, GAIN_STREAM])
        gain = 1.0 + g.uniform(-1, 1, n_taxels) * params.gain_spread
    if params.taxel_gain is not None:
        if taxel_ids is None or len(taxel_ids) != n_taxels:
            raise ValueError("make_skin: [skin].taxel_gain needs the taxel ids")
        gain = load_taxel_gains(params.taxel_gain, taxel_ids)
    return Skin(np.round(base), std, fab, gain, params)


def load_taxel_gains(
    path: str | Path, taxel_ids: np.ndarray, only_these: bool = False
) -> np.ndarray:
    """Gains (T,) of the taxels `taxel_ids` (T,) from a CSV with columns id, gain (e.g.
    `fruit calibrate`'s gains.csv); every taxel must be in it, each gain > 0 and finite;
    with `only_these`, no other taxel either (a file made for another skin)."""
    from fruitcli.tables import read_table

    cols = read_table(path, ["id", "gain"], error=FrameError)
    ids, gains = cols["id"].astype(np.int64), cols["gain"]
    if len(np.unique(ids)) != len(ids):
        raise FrameError(f"{path}: a taxel id appears twice")
    bad = np.flatnonzero(gains <= 0)
    if bad.size:
        raise FrameError(f"{path}: taxel {ids[bad[0]]}: gain expected > 0, got {gains[bad[0]]:g}")
    row = dict(zip(ids.tolist(), range(len(ids)), strict=True))
    missing = [int(t) for t in taxel_ids if int(t) not in row]
    if missing:
        raise FrameError(
            f"{path}: no gain for taxel(s) {', '.join(map(str, missing[:5]))} "
            f"({len(missing)} of {len(taxel_ids)} taxels missing; [skin].taxel_gain "
            "must be made for these taxels)"
        )
    if only_these:
        known = set(int(t) for t in taxel_ids)
        extra = [int(t) for t in ids if int(t) not in known]
        if extra:
            raise FrameError(
                f"{path}: id: gains for taxel(s) {', '.join(map(str, extra[:5]))}"
                f" that the taxel file does not have ({len(ids)} gains for "
                f"{len(taxel_ids)} taxels; made for another skin?)"
            )
    return gains[[row[int(t)] for t in taxel_ids]]


def footprint_sigma_mm(indenter: str, params: SkinParams = DEFAULT_PARAMS) -> float:
    """Lateral Gaussian width of an indenter's activation (mm)."""
    if indenter not in params.footprint_sigma_mm:
        raise FrameError(
            f"indenter: expected one of {', '.join(params.footprint_sigma_mm)}, got {indenter!r}"
        )
    return params.footprint_sigma_mm[indenter]


def activation_counts(
    dist_mm: np.ndarray,
    gap_mm: np.ndarray,
    indenter: str,
    skin: Skin | None = None,
    height_mm: np.ndarray | None = None,
) -> np.ndarray:
    """Mean activation (counts) of taxels at 3D distance `dist_mm` (..., T) from the
    contact point, with the indenter `gap_mm` (...,) above it (negative: pressing in).
    `height_mm` (..., T): the contact point's height over each taxel (z), which the
    skin's ``height_as_distance`` and ``height_as_gap`` weigh; None: as 3D distance. The
    width is sigma (1 + ``widening_per_mm`` g), g the gap (0 for a press) plus the
    height's share."""
    p = DEFAULT_PARAMS if skin is None else skin.params
    sigma = footprint_sigma_mm(indenter, p)
    dist = np.asarray(dist_mm, dtype=float)
    gap = np.asarray(gap_mm, dtype=float)
    approach = np.exp(-gap / p.gap_decay_mm)[..., None]
    spread = np.maximum(gap, 0.0)[..., None]  # the gap the width grows with
    if height_mm is not None and (p.height_as_distance != 1.0 or p.height_as_gap != 0.0):
        h = np.asarray(height_mm, dtype=float)
        dist = np.sqrt(np.maximum(dist**2 + (p.height_as_distance - 1.0) * h * h, 0.0))
        approach = np.exp(-(gap[..., None] + p.height_as_gap * np.abs(h)) / p.gap_decay_mm)
        spread = spread + p.height_as_gap * np.abs(h)
    if p.widening_per_mm:
        sigma = sigma * (1.0 + p.widening_per_mm * spread)
    lateral = np.exp(-0.5 * (dist / sigma) ** 2)
    v = p.contact_counts * lateral * approach
    return v if skin is None or skin.gain is None else v * skin.gain


def surface_green_strain(rest_nodes: np.ndarray, nodes: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """In-plane Green strain norm of each surface triangle: |E| with E = (G0^-1 G - I) / 2,
    G0 and G the triangle's rest and deformed metric (edge dot products).

    rest_nodes (N, 3), nodes (..., N, 3) deformed, tris (F, 3) -> (..., F)."""

    def metric(x: np.ndarray):
        e1, e2 = x[..., 1, :] - x[..., 0, :], x[..., 2, :] - x[..., 0, :]
        g = np.stack(
            [
                np.stack([(e1 * e1).sum(-1), (e1 * e2).sum(-1)], -1),
                np.stack([(e1 * e2).sum(-1), (e2 * e2).sum(-1)], -1),
            ],
            -2,
        )
        return g

    g0 = metric(rest_nodes[tris])
    det = g0[..., 0, 0] * g0[..., 1, 1] - g0[..., 0, 1] ** 2
    ok = det > _DET_EPS
    g0[~ok] = np.eye(2)
    c = np.linalg.inv(g0) @ metric(nodes[..., tris, :])
    e = 0.5 * (c - np.eye(2))
    norm = np.sqrt(np.maximum(np.einsum("...ij,...ji->...", e, e), 0.0))
    return np.where(ok, norm, 0.0)


def taxel_surface_weights(
    rest_nodes: np.ndarray, tris: np.ndarray, taxels_mm: np.ndarray
) -> np.ndarray:
    """(T, F) area weights, rows summing to 1, of the surface triangles around each taxel:
    within ``CROSSING_RADIUS_MM`` of it, parallel to the nearest one and within
    ``CROSSING_PLANE_MM`` of its plane (so the far side of a thin pad is left out;
    the triangles' winding does not matter)."""
    x = rest_nodes[tris]
    cent = x.mean(axis=1)
    cross = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    normal = cross / np.maximum(2 * area, _DET_EPS)[:, None]
    dist = np.linalg.norm(cent[None, :, :] - taxels_mm[:, None, :], axis=2)  # (T, F)
    nearest = dist.argmin(axis=1)
    n0 = normal[nearest]  # (T, 3)
    parallel = np.abs(n0 @ normal.T) > 0.5  # (T, F)
    off_plane = np.abs(np.einsum("tfd,td->tf", cent[None, :, :] - taxels_mm[:, None, :], n0))
    near = (dist <= CROSSING_RADIUS_MM) & parallel & (off_plane <= CROSSING_PLANE_MM)
    w = np.where(near, area[None, :], 0.0)
    w[np.arange(len(taxels_mm)), nearest] += 1e-12  # a taxel always has its own triangle
    return w / w.sum(axis=1, keepdims=True)


def taxel_strain(states: StatesMesh, state_index: int | None = None) -> np.ndarray:
    """Surface strain at each taxel per state: (S, T) (or (T,) for one state): the
    area-weighted in-plane Green strain norm of the surface around the crossing, the
    stretch the sewn yarn feels."""
    idx = slice(None) if state_index is None else state_index
    nodes = states.rest_nodes + states.displacement_mm[idx]
    rest_taxels = np.einsum(
        "tk,tkd->td", states.taxel_bary, states.rest_nodes[states.tets[states.taxel_tet]]
    )
    w = taxel_surface_weights(states.rest_nodes, states.surface_tris, rest_taxels)
    return surface_green_strain(states.rest_nodes, nodes, states.surface_tris) @ w.T


def pad_mesh(
    size_mm: tuple[float, float, float] = PAD_SIZE_MM, step_mm: float = 4.0, layers: int = 4
) -> tuple[np.ndarray, np.ndarray]:
    """A flat pad of tets (`fem.grid.structured_box`): nodes (N, 3), tets (M, 4),
    x and y centred on 0, z in [0, t]."""
    from fruitcli.fem.meshing.grid import structured_box

    sx, sy, t = size_mm
    cells = (int(round(sx / step_mm)), int(round(sy / step_mm)), layers)
    return structured_box((-sx / 2, -sy / 2, 0.0), (sx / 2, sy / 2, t), cells)


def bend_nodes(nodes: np.ndarray, radius_mm: float, thickness_mm: float) -> np.ndarray:
    """Bend a flat pad about the y axis: its mid-plane wraps a cylinder of `radius_mm`,
    the top face (z = thickness) outside."""
    r = radius_mm + nodes[:, 2] - thickness_mm / 2
    th = nodes[:, 0] / radius_mm
    return np.stack(
        [r * np.sin(th), nodes[:, 1], r * np.cos(th) - radius_mm + thickness_mm / 2], axis=1
    )


def pad_taxels_mm(n: int = 4, pitch_mm: float = PAD_PITCH_MM, z_mm: float = 3.0) -> np.ndarray:
    """n x n taxels `pitch_mm` apart centred on the pad's top face (T, 3); i along x."""
    c = (np.arange(n) - (n - 1) / 2) * pitch_mm
    gx, gy = np.meshgrid(c, c, indexing="ij")
    return np.stack([gx.ravel(), gy.ravel(), np.full(n * n, z_mm)], axis=1)


@lru_cache(maxsize=1)
def bent_pad_taxel_strain() -> np.ndarray:
    """Surface strain at each 4 x 4 pad taxel bent 180 deg over its active length (T,)."""
    from fruitcli.fem.meshing.topology import boundary_faces

    nodes, tets = pad_mesh()
    tris = boundary_faces(nodes, tets)
    taxels = pad_taxels_mm(z_mm=PAD_SIZE_MM[2])
    bent = bend_nodes(nodes, PAD_ACTIVE_MM / np.pi, PAD_SIZE_MM[2])
    w = taxel_surface_weights(nodes, tris, taxels)
    return surface_green_strain(nodes, bent, tris) @ w.T


def calibrate_strain_gain() -> float:
    """Counts per unit strain: the bent pad's most strained taxel shifts 10 counts."""
    return BEND_SHIFT_COUNTS / float(bent_pad_taxel_strain().max())


def strain_shift_counts(strain: np.ndarray, skin: Skin, gain: float | None = None) -> np.ndarray:
    """Baseline shift (counts) of each taxel for strains (..., T)."""
    g = calibrate_strain_gain() if gain is None else gain
    return g * skin.fab * np.asarray(strain)


BOARD_MAX_COUNTS = 65535  # the board's counts are 16-bit: they saturate there


def frame_counts(
    mean_counts: np.ndarray, noise_std: np.ndarray | float, rng: np.random.Generator
) -> np.ndarray:
    """Integer counts from mean counts (..., T) plus Gaussian noise of std (T,) (or one
    std for all), within the board's range 0 .. ``BOARD_MAX_COUNTS`` (it saturates, as a
    16-bit counter does)."""
    noisy = mean_counts + rng.standard_normal(mean_counts.shape) * noise_std
    return np.clip(np.round(noisy), 0, BOARD_MAX_COUNTS).astype(np.int64)
