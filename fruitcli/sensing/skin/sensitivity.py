"""Sensitivity analysis (paper Sec. V-A, Figs. 9-11): noise per taxel, baseline shifts.

Units: counts.
"""

from __future__ import annotations

import numpy as np


def noise_std_counts(values: np.ndarray) -> np.ndarray:
    """Standard deviation (counts) of each taxel over a window of frames at rest (N, T)."""
    return np.asarray(values, dtype=float).std(axis=0)


def max_shift_counts(values: np.ndarray, baseline: np.ndarray) -> np.ndarray:
    """Largest |C - C0| (counts) of each taxel over frames (N, T), C0 (T,) at rest."""
    return np.abs(np.asarray(values, dtype=float) - baseline).max(axis=0)


def animation_shift(shift_per_state: np.ndarray, n_frames: int) -> np.ndarray:
    """Shifts (S, T) played once through the states in order over `n_frames` frames,
    linearly interpolated between states -> (n_frames, T)."""
    s = shift_per_state.shape[0]
    u = np.linspace(0.0, s - 1.0, n_frames)
    k = np.minimum(np.floor(u).astype(int), max(s - 2, 0))
    t = (u - k)[:, None]
    k1 = np.minimum(k + 1, s - 1)
    return (1 - t) * shift_per_state[k] + t * shift_per_state[k1]


def summary(values: np.ndarray) -> dict:
    """max and mean of per-taxel values."""
    return {"max": float(np.max(values)), "mean": float(np.mean(values))}
