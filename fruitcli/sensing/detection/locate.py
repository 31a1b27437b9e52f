"""3D touch location (paper eq. 7): the N9 weights applied to the taxels' 3D positions.

Units: mm, kPa.

The taxels' positions come from the frame's deformation state: the rest positions, one
simulated state, or the simulated states interpolated by the frame's chamber pressures.
The states are taken as a path in pressure space (state 0 -> 1 -> ... -> S-1, as the
FEM engineer's actuation sequence); a frame's pressures are projected onto the closest
point of that path (segment s, fraction t in [0, 1]) and the taxels are interpolated
linearly between states s and s + 1.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.sensing.detection.detect import Touches
from fruitcli.tables import read_npz_arrays

STATE_KEYS = (
    "rest_nodes",
    "tets",
    "surface_tris",
    "displacement_mm",
    "pressure_kpa",
    "chamber_names",
    "taxels_mm",
    "taxel_tet",
    "taxel_bary",
)
_SEGMENT_EPS_KPA2 = 1e-12  # segments shorter than this (kPa^2) are points


@dataclass(frozen=True)
class States:
    """FEM states from `fruit simulate` (mm, kPa), same taxel order as the taxel CSV."""

    rest_nodes: np.ndarray  # (N, 3)
    tets: np.ndarray  # (M, 4)
    surface_tris: np.ndarray  # (F, 3)
    displacement_mm: np.ndarray  # (S, N, 3)
    pressure_kpa: np.ndarray  # (S, K)
    chamber_names: tuple[str, ...]
    taxels_mm: np.ndarray  # (S, T, 3)
    taxel_tet: np.ndarray  # (T,)
    taxel_bary: np.ndarray  # (T, 4)

    @property
    def n_states(self) -> int:
        return int(self.taxels_mm.shape[0])

    def nodes_mm(self, state: int) -> np.ndarray:
        """Deformed node positions of `state` (N, 3)."""
        return self.rest_nodes + self.displacement_mm[state]


def load_states(path: str | os.PathLike, n_taxels: int | None = None) -> States:
    """Read states.npz (``allow_pickle=False``) and check shapes; errors name the key."""
    path = Path(path)
    data = read_npz_arrays(path, "states .npz", FrameError)
    missing = [k for k in STATE_KEYS if k not in data]
    if missing:
        raise FrameError(f"{path}: missing key(s) {', '.join(missing)}")
    tax = np.asarray(data["taxels_mm"], dtype=float)
    disp = np.asarray(data["displacement_mm"], dtype=float)
    nodes = np.asarray(data["rest_nodes"], dtype=float)
    press = np.asarray(data["pressure_kpa"], dtype=float)
    if tax.ndim != 3 or tax.shape[2] != 3 or tax.shape[0] < 1:
        raise FrameError(f"{path}: taxels_mm: expected (S, T, 3), got {tax.shape}")
    s, t = tax.shape[:2]
    if n_taxels is not None and t != n_taxels:
        raise FrameError(f"{path}: taxels_mm: {t} taxels, the taxel file has {n_taxels}")
    if disp.shape != (s, nodes.shape[0], 3):
        raise FrameError(
            f"{path}: displacement_mm: expected ({s}, {nodes.shape[0]}, 3), got {disp.shape}"
        )
    if press.ndim != 2 or press.shape[0] != s:
        raise FrameError(f"{path}: pressure_kpa: expected ({s}, K), got {press.shape}")
    for key, arr in (("taxels_mm", tax), ("displacement_mm", disp), ("pressure_kpa", press)):
        if not np.all(np.isfinite(arr)):
            raise FrameError(f"{path}: {key}: NaN or infinite values")
    return States(
        nodes,
        np.asarray(data["tets"], dtype=np.int64),
        np.asarray(data["surface_tris"], dtype=np.int64),
        disp,
        press,
        tuple(str(c) for c in data["chamber_names"]),
        tax,
        np.asarray(data["taxel_tet"], dtype=np.int64),
        np.asarray(data["taxel_bary"], dtype=float),
    )


def state_path_position(
    pressure_kpa: np.ndarray, state_pressure_kpa: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Project frame pressures (N, K) onto the state path (S, K) -> (segment (N,), t (N,))."""
    p = np.asarray(pressure_kpa, dtype=float)
    sp = np.asarray(state_pressure_kpa, dtype=float)
    n, s = p.shape[0], sp.shape[0]
    if s == 1:
        return np.zeros(n, np.int64), np.zeros(n)
    best_d = np.full(n, np.inf)
    seg, frac = np.zeros(n, np.int64), np.zeros(n)
    for k in range(s - 1):
        a, d = sp[k], sp[k + 1] - sp[k]
        dd = float(d @ d)
        t = np.zeros(n) if dd < _SEGMENT_EPS_KPA2 else np.clip((p - a) @ d / dd, 0.0, 1.0)
        dist = np.sum((p - a - t[:, None] * d) ** 2, axis=1)
        better = dist < best_d
        best_d[better], seg[better], frac[better] = dist[better], k, t[better]
    return seg, frac


class StatePath:
    """The state path precomputed for one point at a time (the live loop)."""

    def __init__(self, state_pressure_kpa: np.ndarray):
        sp = np.asarray(state_pressure_kpa, dtype=float)
        self.a = sp[:-1]
        self.d = np.diff(sp, axis=0)
        dd = np.einsum("sk,sk->s", self.d, self.d)
        self.point = dd < _SEGMENT_EPS_KPA2
        self.inv_dd = np.where(self.point, 0.0, 1.0 / np.where(self.point, 1.0, dd))
        self.n_states = sp.shape[0]

    def locate(self, p: np.ndarray) -> tuple[int, float]:
        """(segment, fraction) of the closest point of the path to pressures (K,)."""
        if self.n_states == 1:
            return 0, 0.0
        r = p - self.a
        t = np.clip(np.einsum("sk,sk->s", r, self.d) * self.inv_dd, 0.0, 1.0)
        e = r - t[:, None] * self.d
        k = int(np.argmin(np.einsum("sk,sk->s", e, e)))
        return k, float(t[k])


def match_chambers(names: tuple[str, ...], states: States, where: str) -> np.ndarray:
    """Column order of `names` (a recording's chambers) matching the states' chambers."""
    index = []
    for c in states.chamber_names:
        if c not in names:
            raise FrameError(
                f"{where}: no pressure for chamber {c!r} (recording has "
                f"{', '.join(names) or 'none'})"
            )
        index.append(names.index(c))
    return np.asarray(index, dtype=np.int64)


def touches_3d(
    touches: Touches,
    positions_mm: np.ndarray,
    seg: np.ndarray | None = None,
    frac: np.ndarray | None = None,
) -> np.ndarray:
    """Weighted 3D touch points (n, 3) mm.

    `positions_mm` is (T, 3) (one state for all frames) or (S, T, 3) with per-frame state
    path positions `seg`, `frac` (indexed by ``touches.frame``).
    """
    tax = np.where(touches.taxel < 0, 0, touches.taxel)
    w = touches.weight
    if positions_mm.ndim == 2:
        return np.einsum("nk,nkd->nd", w, positions_mm[tax])
    if seg is None or frac is None:
        raise FrameError("per-state positions need each frame's place on the state path")
    s_last = positions_mm.shape[0] - 1
    s0 = seg[touches.frame]
    s1 = np.minimum(s0 + 1, s_last)
    t = frac[touches.frame][:, None]
    p0 = np.einsum("nk,nkd->nd", w, positions_mm[s0[:, None], tax])
    p1 = np.einsum("nk,nkd->nd", w, positions_mm[s1[:, None], tax])
    return (1.0 - t) * p0 + t * p1
