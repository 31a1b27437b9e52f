"""The virtual 3D-printer bench (paper Sec. V-B): indenters come down until the threshold.

Units: mm, counts, s.

Sample points: "quarter" puts one sample a quarter taxel off each taxel, +spacing_x/4 in
x and +spacing_y/4 in y (the paper's rest truth points sit on a regular lattice; its
sign cannot be read from the paper, we take +). The ground truth has one definition in
every configuration: the contact point is where a vertical line through the sample's
(x, y) first meets the body's surface from above, the body being the reduced surface the
FEM body is made from (``make-tracks/reduced.stl`` or the scene's solid). At rest it is
that surface as it is; in a FEM state its vertices are carried by the FEM's displacement
(each mapped once into its rest tet, like the taxels), so a state with zero displacement
gives exactly the rest truth. Samples whose vertical line misses the body are dropped.
Without a body surface (taxels given directly) the bench falls back to the FEM state's
outer boundary, or at rest to the taxels' own surface interpolated linearly over a
Delaunay triangulation of their (x, y), and says so.

The indenter starts ``START_GAP_MM`` above the contact point and descends by ``step_mm``;
each step is one frame. The first frame in which some taxel's v = C - C0 exceeds the
threshold (C0: the mean of the bench's idle frames) is the sample's frame; the indenter
then lifts for the next sample. Where the board is over the threshold already at the
start (a large object on a sensitive board), the descent starts higher instead, at the
first of ``START_GAPS_MM`` where it is not, so every recorded descent shows the
approach and no frame of it is taken for the previous sample's touch; the recording's
meta ``start_gap_mm`` gives each sample's start. A sample that does not cross the
threshold even ``PRESS_MM`` into the skin is dropped and counted.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.sensing.skin import forward

if TYPE_CHECKING:
    from fruitcli.sensing.skin.crossing_skin import CrossingSkin

START_GAP_MM = 5.0  # indenter start above the contact point
# the starts tried in turn when the board is over the threshold at the one before (the
# last, the printer bench's default safe height, is kept whatever the board reads)
START_GAPS_MM = (START_GAP_MM, 10.0, 20.0)
PRESS_MM = 2.0  # deepest press into the skin before a sample is given up
BENCH_FPS = 60.0  # frame rate of the virtual board (frames/s)


def quarter_samples(
    taxels_xy_mm: np.ndarray, spacing_x_mm: float, spacing_y_mm: float
) -> np.ndarray:
    """(x, y) of one sample a quarter taxel off each taxel (T, 2) mm."""
    return taxels_xy_mm + np.array([spacing_x_mm, spacing_y_mm]) / 4.0


DESCENT_ARRAYS = 6
"""Arrays of one descent's shape (steps, T) alive at once in `descend` (distances,
activation, mean, noise, counts and a mask)."""


def descent_steps(step_mm: float) -> float:
    """Frames of the longest descent, from the last of START_GAPS_MM above contact to
    PRESS_MM into it (about; a float, so that any step > 0 gives a number)."""
    return (START_GAPS_MM[-1] + PRESS_MM) / step_mm + 1.0


def bench_bytes(step_mm: float, samples: int, taxels: int, cells: int) -> float:
    """Most memory (bytes) one indenter's bench may take: one descent's arrays (float64
    per taxel) and, at worst, every sample's full descent kept as frames (int64 per taxel,
    then float64 and uint16 per board cell)."""
    steps = descent_steps(step_mm)
    return steps * taxels * 8.0 * DESCENT_ARRAYS + samples * steps * (8.0 * taxels + 10.0 * cells)


@dataclass
class BenchRun:
    """One indenter's bench recording: taxel counts per frame and the samples' truth."""

    counts: np.ndarray  # (N, T) int counts of the taxels
    sample: np.ndarray  # (N,) int, -1 for idle and approach frames
    truth_mm: np.ndarray  # (m, 3) contact points of the crossed samples
    truth_ids: np.ndarray  # (m,) sample ids (index in the sample list)
    dropped: int  # samples that never crossed the threshold
    start_gap_mm: np.ndarray  # (m,) where each crossed sample's descent started (mm)


def descend(
    contact_mm: np.ndarray,
    taxels_mm: np.ndarray,
    rest_counts: np.ndarray,
    skin: forward.Skin,
    indenter: str,
    step_mm: float,
    idle_frames: int,
    threshold: float,
    rng: np.random.Generator,
    response: CrossingSkin | None = None,
) -> BenchRun:
    """Replay the bench over contact points (P, 3) on taxels at `taxels_mm` (T, 3) whose
    mean counts without touch are `rest_counts` (T,) (baseline + deformation shift).
    `response`: the electrostatic skin (`crossing_skin.CrossingSkin`) for the activation,
    None: the assumed Gaussian (`forward.activation_counts`)."""
    if step_mm <= 0:
        raise FrameError(f"[bench].step_mm: expected > 0, got {step_mm}")
    idle = forward.frame_counts(
        np.broadcast_to(rest_counts, (idle_frames, len(rest_counts))), skin.noise_std_counts, rng
    )
    c0 = idle.mean(axis=0)
    blocks, samples, truth, ids, dropped = [idle], [np.full(idle_frames, -1)], [], [], 0
    starts = []
    if response is not None:
        descent = response.descent(indenter, contact_mm, taxels_mm)
    for k, p in enumerate(contact_mm):
        if response is None:
            dist = np.linalg.norm(taxels_mm - p, axis=1)
            height = p[2] - taxels_mm[:, 2]
        for start in START_GAPS_MM:  # from higher up while the first frame is over
            gaps = np.arange(start, -PRESS_MM - step_mm / 2, -step_mm)
            if response is None:
                touch = forward.activation_counts(
                    dist[None, :], gaps, indenter, skin, height[None, :]
                )
            else:
                touch = descent(k, gaps)
                touch = touch if skin.gain is None else touch * skin.gain
            mean = rest_counts + touch
            counts = forward.frame_counts(mean, skin.noise_std_counts, rng)
            hit = np.flatnonzero((counts - c0 > threshold).any(axis=1))
            if hit.size == 0 or hit[0] > 0:
                break
        if hit.size == 0:
            dropped += 1
            continue
        starts.append(start)
        n = hit[0] + 1
        blocks.append(counts[:n])
        s = np.full(n, -1)
        s[-1] = k
        samples.append(s)
        truth.append(p)
        ids.append(k)
    return BenchRun(
        np.concatenate(blocks),
        np.concatenate(samples),
        np.reshape(truth, (-1, 3)),
        np.asarray(ids, np.int64),
        dropped,
        np.asarray(starts, float),
    )


def cell_counts(
    taxel_counts: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    shape: tuple[int, int],
    fill_counts: np.ndarray,
) -> np.ndarray:
    """Whole frames (N, R, C): taxel cells from `taxel_counts` (N, T), others `fill_counts`
    (N, R, C) (the board reports every crossing, wired or not)."""
    frames = fill_counts.copy()
    frames[:, rows, cols] = taxel_counts
    return frames
