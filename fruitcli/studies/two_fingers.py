"""Two fingers close together on the virtual bench: how often each detection method
reports two touches, and how far they are from the fingers.

Units: mm, counts, pitches (taxel spacings).

The board is a 21 x 12 grid of taxels, ``PITCH_I_MM`` along i and ``PITCH_J_MM`` along j
at rest (the Fruit's two spacings), with the default skin of
`fruitcli.sensing.skin.forward` (seeded baselines and noise, gains 1). Its body is at
rest (flat) or deformed (`BODIES`):

- ``bent``: wrapped about an axis along j on a cylinder of radius ``BEND_RADIUS_MM``
  (lengths along the surface kept);
- ``stretched``: inflated, every length along the surface ``STRETCH`` times its rest
  length, on a sphere of radius ``DOME_RADIUS_MM``.

Two small indenters rest on the surface (gap 0), their activations added (assumption:
the fingers' couplings superpose) and falling with the 3D distance to each taxel where
the body puts it. A point of the surface is given by grid coordinates (fi, fj),
bilinear between the four taxels around it. The fingers' midpoint is drawn uniformly
within one cell around the grid's middle; they are `d` pitches apart along i, along j
or along the grid's diagonal (d cells along both); their distance in mm is the 3D
distance between them (at rest d x 16, d x 12 or d x 20 mm). A frame "separates" them
when it reports exactly two touches; their 3D errors are those of the better of the
two pairings. Single fingers at random points check that a method does not make single
touches worse (exactly one touch, its error). The detection methods see the skin they
were calibrated on, the gap law and footprint of the small indenter
(`heights.gap_law`), and locate as `fruit locate --states` does: the taxel file at
rest (fit2's footprint width in pitches comes from it) and the body's taxel positions.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from fruitcli.sensing.detection.touch_table import TouchTable
    from fruitcli.sensing.skin.forward import Skin

PITCH_I_MM = 16.0
PITCH_J_MM = 12.0
DISTANCES = (0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0)  # pitches
AXES = {"i": (1.0, 0.0), "j": (0.0, 1.0), "diagonal": (1.0, 1.0)}  # grid cells per pitch
METHODS = ("n9", "fit2")
BODIES = ("rest", "bent", "stretched")
BEND_RADIUS_MM = 80.0
STRETCH = 1.25
DOME_RADIUS_MM = 150.0
ROWS, COLS = 21, 12
TRIALS = 40  # frames per axis and distance
SINGLES = 200
IDLE_FRAMES = 10
INDENTER = "small"
HEADER = [
    "body",
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


def body_taxels(body: str) -> np.ndarray:
    """Taxel positions (252, 3) mm of the grid's body (`BODIES`), in taxel order (i, j)."""
    i, j = np.divmod(np.arange(ROWS * COLS), COLS)
    # along the surface, from the grid's middle
    u = PITCH_I_MM * (i - (ROWS - 1) / 2)
    v = PITCH_J_MM * (j - (COLS - 1) / 2)
    if body == "rest":
        return np.stack([PITCH_I_MM * i, PITCH_J_MM * j, 0.0 * i], axis=1)
    if body == "bent":
        r = BEND_RADIUS_MM
        return np.stack([r * np.sin(u / r), v, r * (np.cos(u / r) - 1)], axis=1)
    if body == "stretched":
        r = DOME_RADIUS_MM
        u, v = STRETCH * u, STRETCH * v
        arc = np.hypot(u, v)  # geodesic distance from the top of the dome
        along = np.divide(np.sin(arc / r), arc, out=np.full_like(arc, 1 / r), where=arc > 0)
        return np.stack([r * along * u, r * along * v, r * (np.cos(arc / r) - 1)], axis=1)
    raise ValueError(f"body: expected one of {', '.join(BODIES)}, got {body!r}")


def surface_points(positions: np.ndarray, fi: np.ndarray, fj: np.ndarray) -> np.ndarray:
    """Points (..., 3) mm at grid coordinates (fi, fj): bilinear between the four taxels
    around each of the grid's positions (252, 3)."""
    grid = positions.reshape(ROWS, COLS, 3)
    i0 = np.clip(np.floor(fi).astype(int), 0, ROWS - 2)
    j0 = np.clip(np.floor(fj).astype(int), 0, COLS - 2)
    a, b = (fi - i0)[..., None], (fj - j0)[..., None]
    return (
        (1 - a) * (1 - b) * grid[i0, j0]
        + a * (1 - b) * grid[i0 + 1, j0]
        + (1 - a) * b * grid[i0, j0 + 1]
        + a * b * grid[i0 + 1, j0 + 1]
    )


def _frames(
    positions: np.ndarray, skin: Skin, points: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Frames (N, 21, 12) of indenters at contact at points (N, K, 3) mm over taxels at
    positions (252, 3) mm."""
    from fruitcli.sensing.skin import forward

    dist = np.linalg.norm(positions[None, None] - points[:, :, None, :], axis=3)
    v = forward.activation_counts(dist, np.zeros(points.shape[:2]), INDENTER, skin).sum(axis=1)
    return forward.frame_counts(skin.baseline_counts + v, skin.noise_std_counts, rng).reshape(
        -1, 21, 12
    )


def _pair_errors(t: TouchTable, truth: np.ndarray, frames: int) -> tuple[np.ndarray, np.ndarray]:
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
    seed: int = 0,
    trials: int = TRIALS,
    singles: int = SINGLES,
    distances: Sequence[float] = DISTANCES,
    bodies: Sequence[str] = BODIES,
) -> tuple[list[list], list[list]]:
    """-> (pair rows (HEADER), single rows [body, method, frames, one_rate, median, p95
    mm]), for each body of `bodies` (`BODIES`)."""
    from fruitcli.sensing.detection.frames_to_touches import Locator
    from fruitcli.sensing.detection.settings import Settings
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
    middle = np.array([(ROWS - 1) / 2, (COLS - 1) / 2])
    rows, one_rows = [], []
    for body in bodies:
        pos = body_taxels(body)
        locators = {
            m: Locator(taxels, default_board(), pos, Settings(method=m), heights=law)
            for m in METHODS
        }
        for axis, (ui, uj) in AXES.items():
            for d in distances:
                centre = middle + rng.uniform(-0.5, 0.5, (trials, 2))
                half = 0.5 * d * np.array([ui, uj])
                ends = np.stack([centre - half, centre + half], axis=1)  # (trials, 2, 2)
                truth = surface_points(pos, ends[..., 0], ends[..., 1])
                frames = _frames(pos, skin, truth, rng)
                mm = np.linalg.norm(truth[:, 0] - truth[:, 1], axis=1)
                for m, loc in locators.items():
                    count, err = _pair_errors(loc.batch(frames, base), truth, trials)
                    e = err.ravel()
                    rows.append(
                        [
                            body,
                            axis,
                            d,
                            float(np.mean(mm)),
                            m,
                            trials,
                            float(np.mean(count == 2)),
                            float(np.mean(count == 1)),
                            float(np.mean(count > 2)),
                            float(np.median(e)) if e.size else float("nan"),
                            float(np.percentile(e, 95)) if e.size else float("nan"),
                        ]
                    )
        grid_points = np.array([2.0, 2.0]) + rng.uniform(0, 1, (singles, 2)) * [16.0, 7.0]
        points = surface_points(pos, grid_points[:, 0], grid_points[:, 1])
        frames = _frames(pos, skin, points[:, None, :], rng)
        for m, loc in locators.items():
            t = loc.batch(frames, base)
            count = np.bincount(t.frame, minlength=singles)
            ok = np.flatnonzero(count == 1)
            e = np.array([np.linalg.norm(t.xyz_mm[t.frame == f][0] - points[f]) for f in ok])
            one_rows.append(
                [
                    body,
                    m,
                    singles,
                    float(np.mean(count == 1)),
                    float(np.median(e)) if e.size else float("nan"),
                    float(np.percentile(e, 95)) if e.size else float("nan"),
                ]
            )
    return rows, one_rows


BODY_TEXT = {
    "rest": "at rest (flat)",
    "bent": f"bent on a cylinder of radius {BEND_RADIUS_MM:g} mm about j",
    "stretched": f"stretched x {STRETCH:g} on a dome of radius {DOME_RADIUS_MM:g} mm",
}


def markdown(rows: list[list], one_rows: list[list]) -> str:
    """The tables as markdown: one two-finger table per body, then the single fingers."""
    lines = [
        "# Two fingers close together (virtual bench)",
        "",
        "Separation rate: frames reporting exactly two touches; errors (mm) of those "
        "touches against the nearer finger of the better pairing. Distances in pitches "
        "along the grid; in mm, the mean 3D distance between the fingers.",
    ]
    by = {(r[0], r[1], r[2], r[4]): r for r in rows}
    for body in dict.fromkeys(r[0] for r in rows):
        lines += [
            "",
            f"## Body {BODY_TEXT.get(body, body)}",
            "",
            "| axis | distance (pitches) | distance (mm) | "
            + " | ".join(f"{m}: two / one / more, median / p95 error (mm)" for m in METHODS)
            + " |",
            "|---|---|---|" + "---|" * len(METHODS),
        ]
        for axis in AXES:
            for d in sorted({r[2] for r in rows if r[0] == body and r[1] == axis}):
                cells = []
                for m in METHODS:
                    r = by[(body, axis, d, m)]
                    cells.append(f"{r[6]:.0%} / {r[7]:.0%} / {r[8]:.0%}, {r[9]:.1f} / {r[10]:.1f}")
                lines.append(
                    f"| {axis} | {d:g} | {by[(body, axis, d, METHODS[0])][3]:.1f} | "
                    + " | ".join(cells)
                    + " |"
                )
    lines += [
        "",
        "## Single fingers (random points)",
        "",
        "| body | method | frames | exactly one touch | median error (mm) | p95 error (mm) |",
        "|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {b} | {m} | {n} | {r:.1%} | {med:.2f} | {p95:.2f} |"
        for b, m, n, r, med, p95 in one_rows
    ]
    return "\n".join(lines) + "\n"


def plot(rows: list[list], path: Path) -> None:
    """Separation rate against distance, one panel per axis, one colour per body and one
    line style per method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fruitcli.fsutil import atomic_path

    bodies = list(dict.fromkeys(r[0] for r in rows))
    colours = dict(zip(BODIES, ("tab:blue", "tab:orange", "tab:green"), strict=True))
    fig, axes = plt.subplots(1, len(AXES), figsize=(12, 4.2), sharey=True)
    for ax, axis in zip(axes, AXES, strict=True):
        for body in bodies:
            for m, style in zip(METHODS, ("o:", "s-"), strict=True):
                r = [x for x in rows if x[0] == body and x[1] == axis and x[4] == m]
                ax.plot(
                    [x[2] for x in r],
                    [100 * x[6] for x in r],
                    style,
                    color=colours.get(body),
                    label=f"{m}, {body}",
                    ms=4,
                )
        ax.set_title(f"along {axis}" if axis != "diagonal" else "diagonal")
        ax.set_xlabel("distance between the fingers (pitches)")
        ax.set_ylim(-3, 103)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("frames with two touches (%)")
    axes[-1].legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def write(
    out_dir: str | Path, seed: int = 0, trials: int = TRIALS, bodies: Sequence[str] = BODIES
) -> dict:
    """Run the study; write two_fingers.csv, single_fingers.csv, two_fingers.md and
    two_fingers.png."""
    from fruitcli.fsutil import staged_dir, write_csv, write_text

    rows, one_rows = run(seed, trials, bodies=bodies)
    with staged_dir(out_dir) as tmp:
        write_csv(
            tmp / "two_fingers.csv",
            HEADER,
            rows,
            comments=[
                "two small indenters on the virtual bench's grid, at rest and deformed "
                "(body); rates are shares of frames, distance_mm the mean 3D distance "
                "between the fingers, errors in mm"
            ],
        )
        write_csv(
            tmp / "single_fingers.csv",
            ["body", "method", "frames", "one_rate", "median_error_mm", "p95_error_mm"],
            one_rows,
        )
        write_text(tmp / "two_fingers.md", markdown(rows, one_rows))
        plot(rows, tmp / "two_fingers.png")
    return {"rows": rows, "singles": one_rows}
