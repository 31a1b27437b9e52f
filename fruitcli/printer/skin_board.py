"""Frames of a MuCa-like board whose skin is touched by the printer's indenter.

Units: mm, counts. Each frame is made when it is sent, from the tip's position at that
moment (printer mm -> model mm through `Placement`): the surface under the tip is the
taxels' surface (linear over their xy Delaunay triangles, as the virtual bench at rest),
the gap is the tip's height above it, and the counts are the skin's forward model
(`fruitcli.sensing.skin.forward` with the scene's [skin] parameters: activation at the contact
point below the tip, Gaussian noise, per-taxel baselines and gains), cells without a taxel
at the baseline level. With the electrostatic skin (`response`, a
`crossing_skin.CrossingSkin`) the activation is the crossing table's, as in the virtual
bench: the drop at the taxel's offset from the contact point and the tip's gap above it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.printer.placement import Placement
from fruitcli.sensing.frames.board import taxel_cells
from fruitcli.sensing.skin import forward
from fruitcli.sensing.skin.virtual_bench import cell_counts
from fruitcli.tables import Taxels

if TYPE_CHECKING:
    from fruitcli.scene import BoardSection
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin


class SkinBoard:
    """`frame(k)` -> (rows, cols) counts for the tip where `tip_mm()` says it is now."""

    def __init__(
        self,
        taxels: Taxels,
        board: BoardSection,
        placement: Placement,
        tip_mm: Callable[[], np.ndarray],
        indenter: str = "small",
        seed: int = 0,
        params: forward.SkinParams = forward.DEFAULT_PARAMS,
        response: CrossingSkin | None = None,
    ):
        from scipy.interpolate import LinearNDInterpolator

        if response is None:
            forward.footprint_sigma_mm(indenter, params)  # validates the name
        else:
            response.object_index(indenter)
        self.response = response
        self.taxels_mm = taxels.xyz_mm
        self.rows, self.cols = taxel_cells(taxels, board, "taxels")
        self.shape = (board.rows, board.cols)
        self.placement, self.tip_mm, self.indenter = placement, tip_mm, indenter
        self.skin = forward.make_skin(len(taxels), seed, params, taxels.ids)
        self.rng = np.random.default_rng([seed, 7])
        self.surface = LinearNDInterpolator(self.taxels_mm[:, :2], self.taxels_mm[:, 2])
        self.fill_std = float(np.median(self.skin.noise_std_counts))

    def mean_counts(self, tip_printer_mm: np.ndarray) -> np.ndarray:
        """Noise-free taxel counts (T,) for the tip at printer coordinates (3,)."""
        tip = self.placement.to_model(tip_printer_mm)
        z = float(self.surface(tip[None, :2])[0])
        base = self.skin.baseline_counts.astype(float)
        if not np.isfinite(z):
            return base  # the tip is not over the skin
        contact = np.array([tip[0], tip[1], z])
        gap = np.array([tip[2] - z])
        if self.response is not None:
            act = self.response.activation(self.indenter, contact, self.taxels_mm, gap)[0]
            return base + (act if self.skin.gain is None else act * self.skin.gain)
        dist = np.linalg.norm(self.taxels_mm - contact, axis=1)
        height = (z - self.taxels_mm[:, 2])[None, :]
        act = forward.activation_counts(dist[None, :], gap, self.indenter, self.skin, height)
        return base + act[0]

    def frame(self, k: int) -> np.ndarray:
        mean = self.mean_counts(self.tip_mm())
        taxel = forward.frame_counts(mean[None, :], self.skin.noise_std_counts, self.rng)
        fill = forward.frame_counts(
            np.full((1, *self.shape), forward.BASELINE_COUNTS), self.fill_std, self.rng
        )
        return cell_counts(taxel, self.rows, self.cols, self.shape, fill)[0]
