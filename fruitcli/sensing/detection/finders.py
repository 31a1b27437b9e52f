"""The grid methods' functions in the calling convention of `methods.Method.find`:
``f(flat, grid, threshold, floor, max_touches, footprint) -> Touches``."""

from __future__ import annotations

import numpy as np

from fruitcli.sensing.detection.detect import Grid, Touches, n9_peaks
from fruitcli.sensing.detection.two_footprints import Footprint, fit2_touches


def peaks(
    flat: np.ndarray,
    grid: Grid,
    threshold: float,
    floor: float,
    max_touches: int,
    footprint: Footprint | None,
) -> Touches:
    """Every local maximum's N9 centroid (`detect.n9_peaks`)."""
    return n9_peaks(flat, grid, threshold, floor, max_touches)


def fit2(
    flat: np.ndarray,
    grid: Grid,
    threshold: float,
    floor: float,
    max_touches: int,
    footprint: Footprint | None,
) -> Touches:
    """One or two of the skin's footprints fitted around each peak
    (`two_footprints.fit2_touches`)."""
    if footprint is None:
        raise ValueError("the fit2 method needs the skin's footprint")
    return fit2_touches(flat, grid, threshold, footprint, max_touches)
