"""Localization error against ground truth, as in the paper's Table I.

Errors are Euclidean distances in mm between matched samples; the spread is the
population standard deviation; percentages are relative to a reference length,
by default the largest distance between two truth samples (152 mm on the paper's Fruit).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fruitcli.errors import EvaluationError
from fruitcli.tables import integer_column, read_table

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
    sample = integer_column(path, table, "sample", EvaluationError)
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
    return _largest_distance(_hull_points(np.asarray(truth_xyz, float)))


PAIRS_AT_ONCE = 4_000_000  # distances computed per block (32 MB)


def _hull_points(points: np.ndarray) -> np.ndarray:
    """The points on the convex hull (the two farthest apart are among them): an
    O(n log n) hull instead of all n^2 / 2 distances; joggled, so flat sets work too."""
    if len(points) <= 64:
        return points
    from scipy.spatial import ConvexHull, QhullError

    try:
        return points[ConvexHull(points, qhull_options="QJ").vertices]
    except (QhullError, ValueError):  # all on a line (or one point): its two ends
        centred = points - points.mean(axis=0)
        along = (
            centred
            @ np.linalg.svd(centred[:: max(1, len(points) // 10000)], full_matrices=False)[2][0]
        )
        return points[[int(np.argmin(along)), int(np.argmax(along))]]


def _largest_distance(points: np.ndarray) -> float:
    """Largest distance between two of `points` (n, d), in blocks of rows."""
    rows = max(1, PAIRS_AT_ONCE // len(points))
    best = 0.0
    for start in range(0, len(points), rows):
        block = points[start : start + rows]
        d2 = ((block[:, None, :] - points[None, :, :]) ** 2).sum(axis=2)
        best = max(best, float(d2.max()))
    return float(np.sqrt(best))


BOOTSTRAP_RESAMPLES = 10000
BOOTSTRAP_SEED = 0
BOOTSTRAP_CHUNK = 2_000_000  # indices drawn per batch (16 MB)
BOOTSTRAP_MAX_N = 2000
"""Above this many samples the interval of the mean is the normal one, mean +- 1.96 std /
sqrt(n): the bootstrap costs resamples x n draws and gives the same at that size."""
STAT_KEYS = ("mean_mm", "std_mm", "rmse_mm", "median_mm", "p95_mm", "max_mm")


def bootstrap_ci(
    values: np.ndarray,
    level: float = 0.95,
    resamples: int = BOOTSTRAP_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean of `values` (n,): `resamples` draws of n
    with replacement from a generator seeded with `seed` (same data, same interval)."""
    rng = np.random.default_rng(seed)
    n = len(values)
    chunk = max(1, BOOTSTRAP_CHUNK // n)  # resamples drawn at once: memory stays bounded
    means = np.concatenate(
        [
            values[rng.integers(0, n, size=(min(chunk, resamples - k), n))].mean(axis=1)
            for k in range(0, resamples, chunk)
        ]
    )
    lo, hi = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def error_stats(error_vectors: np.ndarray) -> dict:
    """Statistics of error vectors (n, d) mm (measured - truth): of the norm the mean,
    population std, RMSE, median, 95th percentile, max and the 95 % interval of the mean
    (seeded bootstrap up to BOOTSTRAP_MAX_N samples, normal above); and the mean error
    vector (bias per axis)."""
    err = np.linalg.norm(error_vectors, axis=1)
    if len(err) <= BOOTSTRAP_MAX_N:
        ci, how = list(bootstrap_ci(err)), "bootstrap"
    else:
        half = 1.959964 * float(err.std()) / np.sqrt(len(err))
        ci, how = [float(err.mean()) - half, float(err.mean()) + half], "normal"
    return {
        "mean_mm": float(err.mean()),
        "std_mm": float(err.std()),
        "rmse_mm": float(np.sqrt((err**2).mean())),
        "median_mm": float(np.median(err)),
        "p95_mm": float(np.percentile(err, 95)),
        "max_mm": float(err.max()),
        "bias_mm": [float(v) for v in error_vectors.mean(axis=0)],
        "ci95_mean_mm": ci,
        "ci95_method": how,
    }


def summarize(
    truth_xyz: np.ndarray,
    measured_xyz: np.ndarray,
    reference_length_mm: float | None = None,
    register: str = "none",
    where: str = "measured",
) -> dict:
    """Table I statistics of one row: n, dims, the statistics of `error_stats` after the
    `register` transform (with mean and std also in % of the reference length), the
    transform, and under "compare" the statistics unregistered ("none") and translation
    registered (the paper's protocol). `where` names the measured data in errors."""
    from fruitcli.evaluation.register import register as fit

    if len(truth_xyz) < 1:
        raise EvaluationError(f"{where}: no matched samples")
    if reference_length_mm is None:
        reference_length_mm = reference_length(truth_xyz)
    if not reference_length_mm > 0:
        raise EvaluationError(f"reference length must be > 0 mm, got {reference_length_mm}")
    transform = fit(truth_xyz, measured_xyz, register, where)
    stats = error_stats(transform.apply(measured_xyz) - truth_xyz)
    compare = {"none": error_stats(measured_xyz - truth_xyz)}
    compare["translation"] = error_stats(
        fit(truth_xyz, measured_xyz, "translation", where).apply(measured_xyz) - truth_xyz
    )
    return {
        "n": int(len(truth_xyz)),
        "dims": int(truth_xyz.shape[1]),
        "register": register,
        **stats,
        "mean_pct": 100.0 * stats["mean_mm"] / reference_length_mm,
        "std_pct": 100.0 * stats["std_mm"] / reference_length_mm,
        "reference_length_mm": float(reference_length_mm),
        "transform": transform.as_dict(),
        "transform_text": transform.describe(),
        "compare": compare,
    }
