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
    residual and its outcome. Every column is an array of the table's length: `make`
    fills the ones a detection path does not give."""

    frame: np.ndarray
    touch: np.ndarray
    i: np.ndarray
    j: np.ndarray
    xyz_mm: np.ndarray  # (n, 3)
    peak: np.ndarray
    height_mm: np.ndarray
    height_err_mm: np.ndarray
    strength: np.ndarray
    size_mm: np.ndarray
    kind: np.ndarray  # (n,) int8
    pos_err_mm: np.ndarray  # (n,) the model fit's 1-sigma radius, NaN: none
    residual: np.ndarray  # (n,) its RMS weighted residual, NaN: none
    fit: np.ndarray  # (n,) int8 model_fit.FIT_NONE, FIT_MODEL or FIT_N9

    @classmethod
    def make(
        cls,
        frame: np.ndarray,
        touch: np.ndarray,
        i: np.ndarray,
        j: np.ndarray,
        xyz_mm: np.ndarray,
        peak: np.ndarray,
        height_mm: np.ndarray | None = None,
        height_err_mm: np.ndarray | None = None,
        strength: np.ndarray | None = None,
        size_mm: np.ndarray | None = None,
        kind: np.ndarray | None = None,
        pos_err_mm: np.ndarray | None = None,
        residual: np.ndarray | None = None,
        fit: np.ndarray | None = None,
    ) -> TouchTable:
        """The table of the columns given; those not given (None) are NaN, kinds
        TOUCH and fits FIT_NONE (0)."""
        n = len(frame)

        def nan(column: np.ndarray | None) -> np.ndarray:
            return np.full(n, np.nan) if column is None else column

        return cls(
            frame,
            touch,
            i,
            j,
            xyz_mm,
            peak,
            nan(height_mm),
            nan(height_err_mm),
            nan(strength),
            nan(size_mm),
            np.full(n, TOUCH, np.int8) if kind is None else kind,
            nan(pos_err_mm),
            nan(residual),
            np.zeros(n, np.int8) if fit is None else fit,
        )

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
        """The tables' rows one after another (none: an empty table)."""
        if not tables:
            e = np.zeros(0)
            return cls.make(e.astype(np.int64), e.astype(np.int64), e, e, np.zeros((0, 3)), e)
        return cls(*(np.concatenate([getattr(t, f) for t in tables]) for f in FIELDS))
