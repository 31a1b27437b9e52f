"""Per-taxel health flags over a long run: dead, stuck, saturated, noisy.

Units: counts, frames. Flags, checked on every frame (vectorized over taxels):

- dead: the count has been 0 for `run_frames` frames in a row (no signal: a broken
  yarn, a line the board does not read);
- stuck: the count has not changed for `run_frames` frames while non-zero (a real
  taxel always shows some noise, std 0.5-1.9 counts);
- saturated: the count is at or above `saturation_counts` (the FT5316's 16-bit range);
- noisy: the noise std, estimated from successive quiet frames as
  sqrt(mean((C_n - C_n-1)^2) / 2) (insensitive to slow drift; the mean is a running
  mean over the last ~10 x `run_frames` quiet pairs), exceeds `noisy_std`
  (a quarter of the threshold by default: noise that crosses it at 4 sigma), once
  `run_frames` quiet frame pairs were seen.

Flags are reported (summary, status lines, live view); they do not change detection, but
flagged taxels cannot freeze the drift tracker (`fruitcli.sensing.detection.drift`).
"""

from __future__ import annotations

import numpy as np

RUN_FRAMES = 100
SATURATION_COUNTS = 65535
NOISY_FRACTION = 0.25  # of the threshold


class TaxelHealth:
    def __init__(
        self,
        n_taxels: int,
        threshold_counts: float,
        run_frames: int = RUN_FRAMES,
        saturation_counts: float = SATURATION_COUNTS,
        noisy_std: float | None = None,
    ):
        self.run_frames = run_frames
        self.saturation = saturation_counts
        self.noisy_std = NOISY_FRACTION * threshold_counts if noisy_std is None else noisy_std
        self.prev: np.ndarray | None = None
        self.prev_quiet = False
        self.same = np.zeros(n_taxels, np.int64)
        self.zero = np.zeros(n_taxels, np.int64)
        self.sq_mean = np.zeros(n_taxels)
        self.pairs = 0
        self.saturated = np.zeros(n_taxels, bool)

    def update(self, values: np.ndarray, quiet: bool) -> None:
        """One frame's raw taxel counts (T,); `quiet`: no touch in the frame."""
        if self.prev is not None:
            same = values == self.prev
            self.same = np.where(same, self.same + 1, 0)
            if quiet and self.prev_quiet:
                d = values - self.prev
                self.pairs += 1
                w = max(1.0 / self.pairs, 0.1 / self.run_frames)
                self.sq_mean += w * (d * d - self.sq_mean)
        self.zero = np.where(values == 0, self.zero + 1, 0)
        self.saturated = values >= self.saturation
        self.prev, self.prev_quiet = values.copy(), quiet

    def noise_std(self) -> np.ndarray:
        """(T,) counts, NaN before any quiet pair."""
        if not self.pairs:
            return np.full(self.same.shape, np.nan)
        return np.sqrt(self.sq_mean / 2.0)

    def flags(self) -> dict[str, np.ndarray]:
        """Taxel indices per flag (dead, stuck, saturated, noisy)."""
        dead = self.zero >= self.run_frames
        stuck = (self.same >= self.run_frames) & ~dead
        noisy = np.zeros_like(dead)
        if self.pairs >= self.run_frames:
            noisy = self.noise_std() > self.noisy_std
        return {
            "dead": np.flatnonzero(dead),
            "stuck": np.flatnonzero(stuck),
            "saturated": np.flatnonzero(self.saturated),
            "noisy": np.flatnonzero(noisy),
        }

    def broken(self) -> np.ndarray:
        """(T,) bool: taxels with any flag."""
        out = np.zeros(self.same.shape, bool)
        for idx in self.flags().values():
            out[idx] = True
        return out

    def summary(self, taxel_ids: np.ndarray) -> str:
        """'taxels: dead 3, 7; noisy 12' or 'taxels: all healthy' (taxel ids)."""
        parts = [
            f"{name} {', '.join(str(int(taxel_ids[k])) for k in idx)}"
            for name, idx in self.flags().items()
            if idx.size
        ]
        return "taxels: " + ("; ".join(parts) if parts else "all healthy")
