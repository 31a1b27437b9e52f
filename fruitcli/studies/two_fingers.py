"""Two fingers close together on the virtual bench: how often each detection method
reports two touches, and how far they are from the fingers.

Units: mm, counts, pitches (taxel spacings).

The board is a flat 21 x 12 grid, ``PITCH_I_MM`` along i and ``PITCH_J_MM`` along j (the
Fruit's two spacings), with the default skin of `fruitcli.sensing.skin.forward` (seeded
baselines and noise, gains 1). Two small indenters rest on the surface (gap 0), their
activations added (assumption: the fingers' couplings superpose). Their midpoint is
drawn uniformly within one cell around the grid's middle; they are `d` pitches apart
along i (d x 16 mm), along j (d x 12 mm) or along the grid's diagonal (d x 20 mm: d
cells along both). A frame "separates" them when it reports exactly two touches; their
3D errors are those of the better of the two pairings. Single fingers at random points
check that a method does not make single touches worse (exactly one touch, its error).
The detection methods see the skin they were calibrated on: the gap law and footprint
of the small indenter (`heights.gap_law`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

PITCH_I_MM = 16.0
PITCH_J_MM = 12.0
DISTANCES = (0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0)  # pitches
AXES = {"i": (1.0, 0.0), "j": (0.0, 1.0), "diagonal": (1.0, 1.0)}  # grid cells per pitch
METHODS = ("n9", "fit2")
TRIALS = 40  # frames per axis and distance
SINGLES = 200
IDLE_FRAMES = 10
INDENTER = "small"
HEADER = [
    "axis",
    "distance_pitches",
    "distance_mm",
    "method",
    "frames",
    "two_rate",
    "one_rate",
    "more_rate",
    "median_error_mm",
    "p95_error_mm",
]


def _taxels():
    from fruitcli.tables import Taxels

    i, j = np.divmod(np.arange(21 * 12), 12)
    return Taxels(
        np.arange(i.size), i, j, np.stack([PITCH_I_MM * i, PITCH_J_MM * j, 0.0 * i], axis=1)
    )


def _frames(taxels, skin, points: np.ndarray, rng) -> np.ndarray:
    """Frames (N, 21, 12) of indenters at contact at points (N, K, 3) mm."""
    from fruitcli.sensing.skin import forward

    dist = np.linalg.norm(taxels.xyz_mm[None, None] - points[:, :, None, :], axis=3)
    v = forward.activation_counts(dist, np.zeros(points.shape[:2]), INDENTER, skin).sum(axis=1)
    return forward.frame_counts(skin.baseline_counts + v, skin.noise_std_counts, rng).reshape(
        -1, 21, 12
    )


def _pair_errors(t, truth: np.ndarray, frames: int) -> tuple[np.ndarray, np.ndarray]:
    """(touches per frame (N,), errors (M, 2) mm of the frames with exactly two)."""
    count = np.bincount(t.frame, minlength=frames)
    errs = []
    for f in np.flatnonzero(count == 2):
        p = t.xyz_mm[t.frame == f]
        a = np.linalg.norm(p - truth[f], axis=1)
        b = np.linalg.norm(p[::-1] - truth[f], axis=1)
        errs.append(a if a.sum() <= b.sum() else b)
    return count, np.reshape(errs, (-1, 2))


def run(
    seed: int = 0, trials: int = TRIALS, singles: int = SINGLES, distances=DISTANCES
) -> tuple[list[list], list[list]]:
    """-> (pair rows (HEADER), single rows [method, frames, one_rate, median, p95 mm])."""
    from fruitcli.sensing.detection.frames_to_touches import Locator, Settings
    from fruitcli.sensing.frames.board import default_board
    from fruitcli.sensing.skin import forward
    from fruitcli.sensing.skin.heights import gap_law

    taxels = _taxels()
    skin = forward.make_skin(len(taxels), seed)
    law = gap_law(skin.params, footprint=INDENTER)
    rng = np.random.default_rng(seed)
    idle = forward.frame_counts(
        np.broadcast_to(skin.baseline_counts, (IDLE_FRAMES, 252)), skin.noise_std_counts, rng
    )
    base = idle.mean(axis=0)
    pitch = np.array([PITCH_I_MM, PITCH_J_MM, 0.0])
    middle = np.array([10.0, 5.5, 0.0]) * pitch
    locators = {
        m: Locator(taxels, default_board(), taxels.xyz_mm, Settings(method=m), heights=law)
        for m in METHODS
    }
    rows = []
    for axis, (ui, uj) in AXES.items():
        for d in distances:
            centre = middle + rng.uniform(-0.5, 0.5, (trials, 3)) * pitch * [1, 1, 0]
            half = 0.5 * d * np.array([ui, uj, 0.0]) * pitch
            truth = np.stack([centre - half, centre + half], axis=1)
            frames = _frames(taxels, skin, truth, rng)
            for m, loc in locators.items():
                count, err = _pair_errors(loc.batch(frames, base), truth, trials)
                e = err.ravel()
                rows.append(
                    [
                        axis,
                        d,
                        float(np.linalg.norm(2 * half)),
                        m,
                        trials,
                        float(np.mean(count == 2)),
                        float(np.mean(count == 1)),
                        float(np.mean(count > 2)),
                        float(np.median(e)) if e.size else float("nan"),
                        float(np.percentile(e, 95)) if e.size else float("nan"),
                    ]
                )
    one_rows = []
    points = (
        np.array([2.0, 2.0, 0.0]) + rng.uniform(0, 1, (singles, 3)) * np.array([16.0, 7.0, 0.0])
    ) * pitch
    frames = _frames(taxels, skin, points[:, None, :], rng)
    for m, loc in locators.items():
        t = loc.batch(frames, base)
        count = np.bincount(t.frame, minlength=singles)
        ok = np.flatnonzero(count == 1)
        e = np.array([np.linalg.norm(t.xyz_mm[t.frame == f][0] - points[f]) for f in ok])
        one_rows.append(
            [
                m,
                singles,
                float(np.mean(count == 1)),
                float(np.median(e)),
                float(np.percentile(e, 95)),
            ]
        )
    return rows, one_rows


def markdown(rows: list[list], one_rows: list[list]) -> str:
    """The two tables as markdown."""
    lines = [
        "# Two fingers close together (virtual bench, at rest)",
        "",
        "Separation rate: frames reporting exactly two touches; errors (mm) of those "
        "touches against the nearer finger of the better pairing.",
        "",
        "| axis | distance (pitches) | distance (mm) | "
        + " | ".join(f"{m}: two / one / more, median / p95 error (mm)" for m in METHODS)
        + " |",
        "|---|---|---|" + "---|" * len(METHODS),
    ]
    by = {(r[0], r[1], r[3]): r for r in rows}
    for axis in AXES:
        for d in sorted({r[1] for r in rows if r[0] == axis}):
            cells = []
            for m in METHODS:
                r = by[(axis, d, m)]
                cells.append(f"{r[5]:.0%} / {r[6]:.0%} / {r[7]:.0%}, {r[8]:.1f} / {r[9]:.1f}")
            lines.append(
                f"| {axis} | {d:g} | {by[(axis, d, METHODS[0])][2]:.1f} | "
                + " | ".join(cells)
                + " |"
            )
    lines += [
        "",
        "Single fingers (random points):",
        "",
        "| method | frames | exactly one touch | median error (mm) | p95 error (mm) |",
        "|---|---|---|---|---|",
    ]
    lines += [f"| {m} | {n} | {r:.1%} | {med:.2f} | {p95:.2f} |" for m, n, r, med, p95 in one_rows]
    return "\n".join(lines) + "\n"


def plot(rows: list[list], path: Path) -> None:
    """Separation rate against distance, one panel per axis, one line per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fruitcli.fsutil import atomic_path

    fig, axes = plt.subplots(1, len(AXES), figsize=(11, 3.6), sharey=True)
    for ax, axis in zip(axes, AXES, strict=True):
        for m, style in zip(METHODS, ("o-", "s--"), strict=True):
            r = [x for x in rows if x[0] == axis and x[3] == m]
            ax.plot([x[1] for x in r], [100 * x[5] for x in r], style, label=m)
        ax.set_title(f"along {axis}" if axis != "diagonal" else "diagonal")
        ax.set_xlabel("distance between the fingers (pitches)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("frames with two touches (%)")
    axes[0].legend()
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def write(out_dir, seed: int = 0, trials: int = TRIALS) -> dict:
    """Run the study; write two_fingers.csv, two_fingers.md and two_fingers.png."""
    from fruitcli.fsutil import staged_dir, write_csv, write_text

    rows, one_rows = run(seed, trials)
    with staged_dir(out_dir) as tmp:
        write_csv(
            tmp / "two_fingers.csv",
            HEADER,
            rows,
            comments=[
                "two small indenters at rest on the virtual bench; rates are "
                "shares of frames, errors in mm"
            ],
        )
        write_csv(
            tmp / "single_fingers.csv",
            ["method", "frames", "one_rate", "median_error_mm", "p95_error_mm"],
            one_rows,
        )
        write_text(tmp / "two_fingers.md", markdown(rows, one_rows))
        plot(rows, tmp / "two_fingers.png")
    return {"rows": rows, "singles": one_rows}
