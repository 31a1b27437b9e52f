"""The electrostatic skin (``[skin].model = "electrostatic"``): each taxel's activation and
baseline shift from the crossing's table (`fruitcli.electrostatics`, `fruit skin`)
instead of the assumed footprint, gap decay and strain gain of `forward`.

Units: mm, counts. Counts are ``-counts_per_ff * dC`` (a touch takes field from Rx, so
a touch gives positive counts) and ``-counts_per_ff * (C_delta - C0)``.

- Activation of a taxel at ``t`` for an object whose tip is ``gap`` above the contact
  point ``p``: the table's drop at the lateral offset (p - t)[:2] and the gap
  ``gap + p_z - t_z`` (the indenter comes down vertically), linear in the gap
  between the table's nodes. Below 0 (pressing in: the tip nearer the yarns by as much)
  the drop grows exponentially with the decay of the table's first two gaps under the
  crossing (the indented surface is not modelled); beyond the table's last gap it falls
  exponentially with the decay of its last two gaps; cubic (Catmull-Rom) in (dx, dy)
  within the table's offsets (1.5 pitches either way since version 2 of crossing.npz: every taxel
  of an N9 window and the ring beyond it is solved, not extrapolated); beyond them as
  the Gaussian fitted to the contact row (summary ``footprint_sigma_mm``), continuous
  at the table's edge.
- Baseline shift: per taxel, from the FEM surface around it (the triangles `forward`
  weighs for its strain), the stretch along each yarn (x, y: the grid's axes carried
  onto the surface) and the surface's curvature along it, taken to the neutral plane
  ``NEUTRAL_MM`` under the surface where the table's curvature is. The table's bend of
  curvature k stretches the surface by ``NEUTRAL_MM * k``; so, per yarn, the shift is
  that of the bend at the deformed k less that at the rest k0 (a body curved at rest,
  as the Fruit, has its C0 there) plus that of the stretch left over (surface stretch -
  NEUTRAL_MM * (k - k0)).
  Between the table's strains and curvatures linear, beyond its largest linear from
  its last two, below 0 (compression, concave) the odd extension. Times the taxel's
  fabrication factor (``forward.Skin.fab``), as in the assumed model.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError

if TYPE_CHECKING:
    from collections.abc import Callable

    from fruitcli.electrostatics.design import CrossingInputs
    from fruitcli.sensing.skin.forward import StatesMesh

AXES = ("x", "y")
BLOCK_VALUES = 2_000_000
"""Most table values the bench interpolates across the offsets at once (16 MB)."""


@dataclass(frozen=True)
class CrossingSkin:
    """The crossing's table in counts."""

    objects: tuple[str, ...]
    gap_mm: np.ndarray  # (g,) from 0
    dx_mm: np.ndarray  # (x,) increasing, both signs
    dy_mm: np.ndarray  # (y,)
    drop_counts: np.ndarray  # (k, g, x, y): -counts_per_ff * dC
    sigma_mm: np.ndarray  # (k,) Gaussian footprint fitted at contact
    tail_decay_mm: np.ndarray  # (k,) exponential decay beyond the last gap
    press_decay_mm: np.ndarray  # (k,) exponential growth below contact
    strain: np.ndarray  # (s,) from 0
    curvature_per_mm: np.ndarray  # (c,) from 0
    stretch_counts: np.ndarray  # (2, s) shift stretched along x, y
    bend_counts: np.ndarray  # (2, c) shift bent along x, y
    neutral_mm: float
    counts_per_ff: float

    @classmethod
    def from_table(
        cls, arrays: dict, summary: dict, counts_per_ff: float | None = None
    ) -> CrossingSkin:
        """From crossing.npz's arrays and summary.json's dict (`fruitcli.electrostatics.
        design`), in counts of `counts_per_ff` (default: the summary's, fitted to the
        bent pad)."""
        from fruitcli.electrostatics.crossing import NEUTRAL_MM

        scale = float(summary["counts_per_ff"] if counts_per_ff is None else counts_per_ff)
        c0 = float(arrays["c0_ff"])
        objects = tuple(str(o) for o in arrays["objects"])
        gap = np.asarray(arrays["gap_mm"], float)
        drop = -scale * np.asarray(arrays["dc_ff"], float)
        dx, dy = np.asarray(arrays["dx_mm"], float), np.asarray(arrays["dy_mm"], float)
        cx, cy = int(np.argmin(np.abs(dx))), int(np.argmin(np.abs(dy)))
        tail, press = [], []
        for k, name in enumerate(objects):
            under = drop[k, :, cx, cy]
            fallback = float(summary["objects"][name].get("gap_decay_mm") or 1.0)
            tail.append(_decay_mm(gap[-2:], under[-2:], fallback))
            press.append(_decay_mm(gap[:2], under[:2], fallback))
        sigma = [float(summary["objects"][n]["footprint_sigma_mm"]) for n in objects]
        return cls(
            objects,
            gap,
            dx,
            dy,
            drop,
            np.array(sigma),
            np.array(tail),
            np.array(press),
            np.asarray(arrays["strain"], float),
            np.asarray(arrays["curvature_per_mm"], float),
            -scale * (np.asarray(arrays["c_stretch_ff"], float) - c0),
            -scale * (np.asarray(arrays["c_bend_ff"], float) - c0),
            float(NEUTRAL_MM),
            scale,
        )

    @classmethod
    def load(cls, folder: Path, counts_per_ff: float | None = None) -> CrossingSkin:
        """From `fruit skin`'s folder (crossing.npz, summary.json)."""
        folder = Path(folder)
        try:
            with np.load(folder / "crossing.npz", allow_pickle=False) as data:
                arrays = {k: data[k] for k in data.files}
            summary = json.loads((folder / "summary.json").read_text())
        except (OSError, ValueError, KeyError) as exc:
            raise FrameError(
                f"{folder}: the crossing's table (crossing.npz, summary.json) cannot be read: {exc}"
            ) from None
        return cls.from_table(arrays, summary, counts_per_ff)

    def object_index(self, indenter: str) -> int:
        if indenter not in self.objects:
            raise FrameError(
                f"indenter: expected one of the crossing table's objects "
                f"({', '.join(self.objects)}), got {indenter!r}"
            )
        return self.objects.index(indenter)

    def drop(
        self,
        indenter: str,
        dx_mm: np.ndarray | float,
        dy_mm: np.ndarray | float,
        gap_mm: np.ndarray | float,
    ) -> np.ndarray:
        """The forward law: activation (counts) of a taxel with `indenter` at lateral
        offsets dx, dy (mm, the touch's point less the taxel's) and gaps (mm, tip above
        the surface; below 0 pressing in), arrays broadcast together; interpolated in
        the table as `activation` is."""
        k = self.object_index(indenter)
        dx, dy, gap = np.broadcast_arrays(*(np.asarray(v, float) for v in (dx_mm, dy_mm, gap_mm)))
        profile = self._lateral(k, dx.ravel(), dy.ravel())
        g = gap.ravel()
        out = self._along_gap(k, profile, np.zeros(1), np.maximum(g, 0.0))[0]
        out *= np.exp(np.maximum(-g, 0.0) / self.press_decay_mm[k])  # pressing in
        return out.reshape(dx.shape)

    def activation(
        self, indenter: str, contact_mm: np.ndarray, taxels_mm: np.ndarray, gaps_mm: np.ndarray
    ) -> np.ndarray:
        """(G, T) counts of taxels (T, 3) with the indenter `gaps_mm` (G,) above the
        contact point (3,). The table is interpolated across (dx, dy) once per taxel, then
        along the gap for every frame: the same values as `drop`."""
        k = self.object_index(indenter)
        off = np.asarray(contact_mm, float) - taxels_mm  # (T, 3)
        profile = self._lateral(k, off[:, 0], off[:, 1])
        return self._along_gap(k, profile, np.asarray(gaps_mm, float), off[:, 2])

    def descent(
        self, indenter: str, contact_mm: np.ndarray, taxels_mm: np.ndarray
    ) -> Callable[[int, np.ndarray], np.ndarray]:
        """A function (p, gaps (G,)) -> (G, T) counts of taxels (T, 3) with the indenter
        above contact point p of `contact_mm` (P, 3): `activation` with the lateral
        interpolation done for a block of contact points at once (the bench's descents;
        blocks of at most ``BLOCK_VALUES`` table values)."""
        k = self.object_index(indenter)
        off = np.asarray(contact_mm, float)[:, None, :] - taxels_mm  # (P, T, 3)
        size = max(1, BLOCK_VALUES // (off.shape[1] * (len(self._uniform[1][k][0]))))
        block: dict[int, np.ndarray] = {}  # the block of contact points from a start

        def at_gaps(p: int, gaps_mm: np.ndarray) -> np.ndarray:
            start = p - p % size
            if start not in block:
                flat = off[start : start + size].reshape(-1, 3)
                block.clear()
                block[start] = self._lateral(k, flat[:, 0], flat[:, 1]).reshape(
                    -1, off.shape[1], len(self._uniform[1][k][0])
                )
            profile = block[start][p - start]
            return self._along_gap(k, profile, np.asarray(gaps_mm, float), off[p, :, 2])

        return at_gaps

    def _lateral(self, k: int, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
        """(N, u + 1) the table's column at each of N offsets, on the uniform gap grid
        (`_uniform`): cubic convolution (Catmull-Rom: through the table's values, with
        a continuous slope) within the table's offsets, beyond them its edge value
        times the contact Gaussian's fall-off."""
        cx = np.minimum(np.maximum(dx, self.dx_mm[0]), self.dx_mm[-1])
        cy = np.minimum(np.maximum(dy, self.dy_mm[0]), self.dy_mm[-1])
        ix, wx = _cubic(self.dx_mm, cx)  # (N, 4) each
        iy, wy = _cubic(self.dy_mm, cy)
        table = self._uniform[1][k]  # (x y, u)
        ny = len(self.dy_mm)
        corners = (ix[:, :, None] * ny + iy[:, None, :]).reshape(len(dx), 16)
        weights = (wx[:, :, None] * wy[:, None, :]).reshape(len(dx), 16)
        v = weights[:, :1] * table[corners[:, 0]]
        for c in range(1, 16):  # a corner at a time: (N, u) in memory, not (N, 16, u)
            v += weights[:, c : c + 1] * table[corners[:, c]]
        outside = (dx**2 - cx**2) + (dy**2 - cy**2)
        if outside.any():
            v *= np.exp(-0.5 * outside / self.sigma_mm[k] ** 2)[:, None]
        return v

    def _along_gap(self, k: int, profile: np.ndarray, rows: np.ndarray, cols: np.ndarray):
        """(G, N) `profile` (N, u + 1) at the indenter's gaps `rows` (G,) above its contact
        point (negative: pressing in) and the contact point's heights `cols` (N,) over each
        crossing: linear between the grid's gaps at max(row, 0) + |col| (a crossing above
        the contact point, on a body curving away under the indenter, is as far from it as
        one below), exponential beyond the last gap, and a press below contact raising
        every crossing alike. The grid is uniform, so a gap's interval is arithmetic; the
        passes over (G, N) are few and in place (the bench calls this for every frame)."""
        step, _ = self._uniform
        top, n = float(self.gap_mm[-1]), profile.shape[1]
        gap = np.maximum(rows, 0.0)[:, None] + np.abs(cols)
        u = np.clip(gap, 0.0, top)
        u *= 1.0 / step
        at = u.astype(np.intp)  # up to u's last node: the profile repeats it
        u -= at  # the weight of the upper node
        at += np.arange(profile.shape[0]) * n  # the lower node's index in the profile
        flat = profile.ravel()
        v = flat[at]
        at += 1
        upper = flat[at]
        upper -= v
        upper *= u
        v += upper
        pressed = np.flatnonzero(rows < 0)  # rows with the indenter below contact
        if pressed.size:
            v[pressed] *= np.exp(-rows[pressed] / self.press_decay_mm[k])[:, None]
        far = np.flatnonzero(rows + np.abs(cols).max() > top)
        if far.size:
            v[far] *= np.exp(-np.maximum(gap[far] - top, 0.0) / self.tail_decay_mm[k])
        return v

    @property
    def _uniform(self) -> tuple[float, np.ndarray]:
        """(step mm, drop_counts (k, x y, u + 1)): the table on a uniform gap grid from 0
        to its last gap (the last repeated once) whose step divides every gap of the
        table, so linear interpolation on it is linear interpolation on the table (made
        once)."""
        cached = self.__dict__.get("_uniform_cache")
        if cached is None:
            step = _common_step(self.gap_mm)
            grid = np.linspace(0.0, self.gap_mm[-1], round(self.gap_mm[-1] / step) + 1)
            i, w = _cell(self.gap_mm, grid)
            table = (
                self.drop_counts[:, i] * (1 - w)[:, None, None]
                + self.drop_counts[:, i + 1] * w[:, None, None]
            )
            table = np.concatenate([table, table[:, -1:]], axis=1)  # the last repeated
            by_offset = np.moveaxis(table, 1, -1)  # (k, x, y, u + 1)
            cached = (
                float(grid[1] - grid[0]),
                np.ascontiguousarray(by_offset.reshape(len(table), -1, len(grid) + 1)),
            )
            object.__setattr__(self, "_uniform_cache", cached)
        return cached

    def deformation_shift(
        self,
        stretch: np.ndarray,
        curvature_per_mm: np.ndarray,
        rest_curvature_per_mm: np.ndarray | float = 0.0,
    ) -> np.ndarray:
        """Baseline shift (counts) for the surface's stretches and curvatures (..., 2)
        along x, y, from its curvatures at rest (..., 2) (0: flat). The table's curvature
        is its neutral plane's, ``neutral_mm`` under the surface: k = k_s / (1 -
        neutral_mm k_s) from the surface's k_s."""
        stretch = np.asarray(stretch, float)
        kappa = self._neutral(curvature_per_mm)
        kappa0 = np.broadcast_to(self._neutral(rest_curvature_per_mm), kappa.shape)
        total = np.zeros(kappa.shape[:-1])
        for a in range(2):
            left = stretch[..., a] - self.neutral_mm * (kappa[..., a] - kappa0[..., a])
            total = total + (
                _odd_interp(kappa[..., a], self.curvature_per_mm, self.bend_counts[a])
                - _odd_interp(kappa0[..., a], self.curvature_per_mm, self.bend_counts[a])
            )
            total = total + _odd_interp(left, self.strain, self.stretch_counts[a])
        return total

    def _neutral(self, surface_curvature_per_mm: np.ndarray | float) -> np.ndarray:
        surface = np.asarray(surface_curvature_per_mm, float)
        return surface / np.maximum(1.0 - self.neutral_mm * surface, 0.1)


def _cell(nodes: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the interval of increasing `nodes` holding each `x` (clipped to them) and
    the weight of its upper node."""
    i = np.minimum(np.maximum(np.searchsorted(nodes, x, side="right") - 1, 0), len(nodes) - 2)
    return i, (x - nodes[i]) / (nodes[i + 1] - nodes[i])


def _cubic(nodes: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 4) node indices and Catmull-Rom weights of `x` (N,) inside `nodes` (equally
    spaced in a table; otherwise the same weights at the fraction of the interval); the
    end nodes stand for the ones beyond (the weights still sum to 1)."""
    i, t = _cell(nodes, x)
    t2, t3 = t * t, t * t * t
    w = 0.5 * np.stack(
        [-t3 + 2 * t2 - t, 3 * t3 - 5 * t2 + 2, -3 * t3 + 4 * t2 + t, t3 - t2], axis=1
    )
    idx = np.clip(i[:, None] + np.arange(-1, 3), 0, len(nodes) - 1)
    return idx, w


def _common_step(gaps: np.ndarray, most: int = 4096) -> float:
    """The largest step (mm) that divides every gap (from 0) within 1e-9 mm, at most
    `most` steps to the last gap; else the last gap / `most` (then linear on the grid
    departs from linear on the table by at most the curvature over a 1/most step)."""
    top = float(gaps[-1])
    for n in range(1, most + 1):
        k = gaps * (n / top)
        if np.all(np.abs(k - np.round(k)) * (top / n) < 1e-9):
            return top / n
    return top / most


def _decay_mm(gaps: np.ndarray, drops: np.ndarray, fallback: float) -> float:
    """Length (mm) over which `drops` (2,) at `gaps` (2,) fall by 1/e; `fallback` when
    they do not fall."""
    rate = np.log(max(drops[0], 1e-12) / max(drops[1], 1e-12)) / (gaps[1] - gaps[0])
    return float(1.0 / rate) if rate > 0 else fallback


def _odd_interp(x: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """ys over xs (from 0) at |x|, linear between, extrapolated from the last two points
    beyond, sign(x) times (the odd extension below 0)."""
    ax = np.abs(x)
    slope = (ys[-1] - ys[-2]) / (xs[-1] - xs[-2])
    v = np.where(ax <= xs[-1], np.interp(ax, xs, ys), ys[-1] + slope * (ax - xs[-1]))
    return np.sign(x) * (v - ys[0])


def yarn_deformation(
    states: StatesMesh, state_index: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(stretch, curvature_per_mm), each (S, T, 2) (or (T, 2) for one state): the surface
    around each taxel (`forward.taxel_surface_weights`) stretched and curved along the
    yarns (the grid's x and y carried onto the surface). Stretch: the weighted mean of
    |F t| - 1 over the triangles (F the triangle's in-plane deformation, t the yarn's
    rest direction in its plane); curvature: the weighted least-squares slope of the
    outward normal's component along the deformed yarn direction against the position
    along it (positive: convex, the surface outside)."""
    idx = slice(None) if state_index is None else state_index
    moved = states.rest_nodes + np.asarray(states.displacement_mm[idx])
    single = moved.ndim == 2
    stretch, curv = surface_deformation(states, moved[None] if single else moved)
    return (stretch[0], curv[0]) if single else (stretch, curv)


def surface_deformation(states: StatesMesh, moved: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`yarn_deformation` of the states' surface with its nodes at `moved` (S, N, 3):
    (stretch, curvature_per_mm), each (S, T, 2)."""
    from fruitcli.sensing.skin import forward

    rest = states.rest_nodes
    tris = states.surface_tris
    rest_taxels = np.einsum("tk,tkd->td", states.taxel_bary, rest[states.tets[states.taxel_tet]])
    w_all = forward.taxel_surface_weights(rest, tris, rest_taxels)
    x0 = rest[tris]  # (F, 3, 3)
    a_edges = np.stack([x0[:, 1] - x0[:, 0], x0[:, 2] - x0[:, 0]], axis=-1)  # (F, 3, 2)
    x = moved[:, tris]  # (S, F, 3, 3)
    b_edges = np.stack([x[:, :, 1] - x[:, :, 0], x[:, :, 2] - x[:, :, 0]], axis=-1)
    n_rest = _unit(np.cross(a_edges[..., 0], a_edges[..., 1]))
    area_normal = np.cross(b_edges[..., 0], b_edges[..., 1])  # (S, F, 3)
    vertex_normal = np.zeros(moved.shape)
    for c in range(3):
        # numpy's stubs lack ufunc.at's tuple index (a slice, then indices)
        np.add.at(vertex_normal, (slice(None), tris[:, c]), area_normal)  # type: ignore[arg-type]
    vertex_normal = _unit(vertex_normal)  # (S, N, 3)
    n_states, n_taxels = moved.shape[0], len(rest_taxels)
    stretch = np.zeros((n_states, n_taxels, 2))
    curv = np.zeros((n_states, n_taxels, 2))
    for t in range(n_taxels):
        f = np.flatnonzero(w_all[t] > 1e-9)
        w = w_all[t, f] / w_all[t, f].sum()
        n0 = _unit(w @ n_rest[f])
        tx = np.array([1.0, 0.0, 0.0]) - n0[0] * n0
        tx = _unit(tx if np.linalg.norm(tx) > 1e-6 else np.cross(np.array([0.0, 1.0, 0.0]), n0))
        for a, axis_dir in enumerate((tx, np.cross(n0, tx))):
            tf = axis_dir - (n_rest[f] @ axis_dir)[:, None] * n_rest[f]
            tf = _unit(tf)
            a_f = a_edges[f]
            gram = np.einsum("fdi,fdj->fij", a_f, a_f)
            coef = np.linalg.solve(gram, np.einsum("fdi,fd->fi", a_f, tf)[..., None])[..., 0]
            ft = np.einsum("sfdi,fi->sfd", b_edges[:, f], coef)  # (S, f, 3)
            stretch[:, t, a] = np.linalg.norm(ft, axis=-1) @ w - 1.0
            t_def = _unit(np.einsum("sfd,f->sd", ft, w))  # (S, 3)
            verts = tris[f].ravel()
            wv = np.repeat(w, 3) / 3.0
            pos = np.einsum("svd,sd->sv", moved[:, verts], t_def)
            nrm = np.einsum("svd,sd->sv", vertex_normal[:, verts], t_def)
            pos = pos - (pos @ wv)[:, None]
            nrm = nrm - (nrm @ wv)[:, None]
            var = (pos**2) @ wv
            surface = np.where(var > 1e-9, ((pos * nrm) @ wv) / np.maximum(var, 1e-9), 0.0)
            curv[:, t, a] = surface
    return stretch, curv


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def shift_counts(
    states: StatesMesh, response: CrossingSkin, fab: np.ndarray, state_index: int | None = None
) -> np.ndarray:
    """Baseline shift (counts) of each taxel from the rest shape: (S, T) (or (T,) for
    one state)."""
    stretch, curv = yarn_deformation(states, state_index)
    _, rest_curv = surface_deformation(states, states.rest_nodes[None])
    return response.deformation_shift(stretch, curv, rest_curv[0]) * fab


@dataclass(frozen=True)
class CrossingSkinInputs:
    """What an electrostatic skin's crossing table in counts is made from: ``[skin].
    counts_per_ff`` (None: the table's own fit) and its `source`, either the skin stage's
    folder (its crossing.npz and summary.json) or the crossing cell's inputs
    (`fruitcli.electrostatics.design.crossing_inputs`), computed now. The sensing stages
    build it (`fruitcli.sensing.inputs_stage.crossing_skin_inputs`)."""

    counts_per_ff: float | None
    source: Path | CrossingInputs


def crossing_skin(
    inputs: CrossingSkinInputs, progress: Callable[[str], None] | None = None
) -> CrossingSkin:
    """The electrostatic skin's crossing table in counts (of ``counts_per_ff`` when
    given): read from the skin stage's folder or computed now from the cell's inputs
    (`fruitcli.electrostatics.design`, telling `progress`)."""
    if isinstance(inputs.source, Path):
        return CrossingSkin.load(inputs.source, inputs.counts_per_ff)
    from fruitcli.electrostatics import design

    table, summary = design.run_crossing(inputs.source, progress=progress)
    return CrossingSkin.from_table(design.table_arrays(table), summary, inputs.counts_per_ff)
