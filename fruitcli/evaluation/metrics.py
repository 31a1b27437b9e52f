"""Localization error against ground truth, as in the paper's Table I.

Errors are Euclidean distances in mm between matched samples; the spread is the
population standard deviation; percentages are relative to a reference length,
by default the largest distance between two truth samples (152 mm on the paper's Fruit).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.distance import pdist

from fruitcli.errors import EvaluationError
from fruitcli.tables import read_table

AXES_3D = ("x_mm", "y_mm", "z_mm")


@dataclass
class PointSet:
    """Samples with coordinates: `sample (n,) int`, `xyz (n, d) mm`, d = 2 (top view) or 3."""

    path: Path
    sample: np.ndarray
    xyz: np.ndarray

    @property
    def dims(self) -> int:
        return self.xyz.shape[1]


def read_points(path: str | Path) -> PointSet:
    """Read `sample,x_mm,y_mm[,z_mm]`; z is used when the file has it."""
    path = Path(path)
    table = read_table(path, ["sample", "x_mm", "y_mm"], error=EvaluationError)
    axes = [a for a in AXES_3D if a in table]
    if "z_mm" in table:
        ztab = read_table(path, ["sample", *AXES_3D], error=EvaluationError)
        table = ztab
    sample = table["sample"]
    if np.any(sample != np.round(sample)):
        raise EvaluationError(f"{path}: column sample: expected integers")
    sample = sample.astype(int)
    uniq, counts = np.unique(sample, return_counts=True)
    if np.any(counts > 1):
        raise EvaluationError(f"{path}: column sample: duplicate sample {uniq[counts > 1][0]}")
    xyz = np.column_stack([table[a] for a in axes])
    return PointSet(path, sample, xyz)


def match(truth: PointSet, measured: PointSet) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pair samples by id. Returns (sample, truth (n,d), measured (n,d)) with d the common
    dimension (2 when either file is top view only)."""
    t_ids, m_ids = set(truth.sample.tolist()), set(measured.sample.tolist())
    missing = sorted(t_ids - m_ids)
    extra = sorted(m_ids - t_ids)
    if missing or extra:
        parts = []
        if missing:
            parts.append(f"missing sample(s) {_ids(missing)} present in {truth.path.name}")
        if extra:
            parts.append(f"extra sample(s) {_ids(extra)} not in {truth.path.name}")
        raise EvaluationError(f"{measured.path}: " + "; ".join(parts))
    d = min(truth.dims, measured.dims)
    order_t = np.argsort(truth.sample)
    order_m = np.argsort(measured.sample)
    return truth.sample[order_t], truth.xyz[order_t, :d], measured.xyz[order_m, :d]


def _ids(ids: list[int]) -> str:
    shown = ", ".join(str(i) for i in ids[:8])
    return shown + (f" and {len(ids) - 8} more" if len(ids) > 8 else "")


def reference_length(truth_xyz: np.ndarray) -> float:
    """Largest distance between two truth samples (mm)."""
    if len(truth_xyz) < 2:
        raise EvaluationError("need at least two truth samples for a reference length")
    return float(pdist(truth_xyz).max())


def summarize(truth_xyz: np.ndarray, measured_xyz: np.ndarray,
              reference_length_mm: float | None = None) -> dict:
    """Table I statistics: n, dims, mean/std of the error norm in mm and % of the reference."""
    if reference_length_mm is None:
        reference_length_mm = reference_length(truth_xyz)
    if not reference_length_mm > 0:
        raise EvaluationError(f"reference length must be > 0 mm, got {reference_length_mm}")
    err = np.linalg.norm(measured_xyz - truth_xyz, axis=1)
    mean, std = float(err.mean()), float(err.std())
    return {
        "n": int(len(err)),
        "dims": int(truth_xyz.shape[1]),
        "mean_mm": mean,
        "std_mm": std,
        "mean_pct": 100.0 * mean / reference_length_mm,
        "std_pct": 100.0 * std / reference_length_mm,
        "reference_length_mm": float(reference_length_mm),
    }
