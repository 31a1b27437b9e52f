"""The table of touches every detection path writes: one row per touch of a frame.

Units: mm, counts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TOUCH, HOVER = 0, 1  # TouchTable.kind
KIND_NAMES = ("touch", "hover")

FIELDS = (
    "frame",
    "touch",
    "i",
    "j",
    "xyz_mm",
    "peak",
    "height_mm",
    "height_err_mm",
    "strength",
    "size_mm",
    "kind",
    "pos_err_mm",
    "residual",
    "fit",
)


@dataclass
class TouchTable:
    """One row per touch: frame index, touch (rank or ID), grid i, j, point (mm), peak
    (counts), height above the surface and its 1-sigma uncertainty (mm), strength
    (1: contact), footprint size (mm, see `touch_shape`), kind (TOUCH or HOVER) and,
    with the model method (`model_fit`), the point's 1-sigma radius (mm), the fit's
    residual and its outcome. Shapes not given are NaN, kinds TOUCH, fits FIT_NONE."""

    frame: np.ndarray
    touch: np.ndarray
    i: np.ndarray
    j: np.ndarray
    xyz_mm: np.ndarray  # (n, 3)
    peak: np.ndarray
    height_mm: np.ndarray | None = None
    height_err_mm: np.ndarray | None = None
    strength: np.ndarray | None = None
    size_mm: np.ndarray | None = None
    kind: np.ndarray | None = None  # (n,) int8
    pos_err_mm: np.ndarray | None = None  # (n,) the model fit's 1-sigma radius, NaN: none
    residual: np.ndarray | None = None  # (n,) its RMS weighted residual, NaN: none
    fit: np.ndarray | None = None  # (n,) int8 model_fit.FIT_NONE, FIT_MODEL or FIT_N9

    def __post_init__(self):
        n = len(self.frame)
        for name in ("height_mm", "height_err_mm", "strength", "size_mm", "pos_err_mm", "residual"):
            if getattr(self, name) is None:
                setattr(self, name, np.full(n, np.nan))
        if self.kind is None:
            self.kind = np.full(n, TOUCH, np.int8)
        if self.fit is None:
            self.fit = np.zeros(n, np.int8)

    def __len__(self) -> int:
        return int(self.frame.shape[0])

    def rows(self, keep: np.ndarray) -> TouchTable:
        """The rows `keep` (a mask or indices)."""
        return TouchTable(*(getattr(self, f)[keep] for f in FIELDS))

    def touches_only(self) -> TouchTable:
        """The touches, without the hovers."""
        return self if not (self.kind == HOVER).any() else self.rows(self.kind == TOUCH)

    @classmethod
    def concat(cls, tables: list[TouchTable]) -> TouchTable:
        if not tables:
            e = np.zeros(0)
            return cls(e.astype(np.int64), e.astype(np.int64), e, e, np.zeros((0, 3)), e)
        return cls(*(np.concatenate([getattr(t, f) for t in tables]) for f in FIELDS))
