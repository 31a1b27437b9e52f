"""Where the taxels place a touch: which bench samples lie inside the taxels' outline
seen from above, and the translation-registered mean error of matched points (as Table
I's rows are registered).

A sample past the outline (a quarter pitch beyond the last column of a curved body, such
as the Fruit's flank) is seen from one side only: how far out it lies trades against
its amplitude, and one frame bounds it only to several millimetres
(`tests/performance/locate_bound.py`). `fruit study locate` reports the error inside
the outline beside the whole row's, and `studies.model_frames` chooses the model's
frames on the samples inside. Units: mm.
"""

from __future__ import annotations

import numpy as np


def inside_outline(points_mm: np.ndarray, taxels_mm: np.ndarray) -> np.ndarray:
    """Which points (n, 3) lie inside the taxels' outline seen from above: the convex
    hull of their x, y."""
    from scipy.spatial import Delaunay

    if len(points_mm) == 0:
        return np.zeros(0, bool)
    return Delaunay(taxels_mm[:, :2]).find_simplex(points_mm[:, :2]) >= 0


def registered_mean(truth: np.ndarray, measured: np.ndarray) -> float:
    """Translation-registered mean error (mm) of matched points (n, 3), registered as
    Table I's rows are (`fruitcli.evaluation.register`); NaN for none."""
    from fruitcli.evaluation.register import register

    if len(truth) == 0:
        return float("nan")
    moved = register(truth, measured, "translation").apply(measured)
    return float(np.linalg.norm(moved - truth, axis=1).mean())
