"""Yarn stretch along the tracks through the simulated states (paper Sec. III-D).

The paper sews DataStretch yarn along the tracks in a slight zig-zag: the yarn stretches
at most about 30 % and its stiffness should not act on the silicone. Each track's centre
line (on the rest surface) is located in the FEM's elements once, at rest, and follows
them with the model's shape functions (as the taxels do); its length in every state
against its rest length is its stretch. A sewn yarn is held at each stitch, so what
matters is also the largest stretch over any piece one zig-zag pitch long (the local
stretch); the warnings use it. The zig-zag that gives that much slack is a triangle wave
of amplitude A at pitch p: it straightens fully when the track stretches by
sqrt(1 + (4 A / p)^2) - 1; the slack quoted is the whole stretch, so that the yarn stays
slack and its stiffness does not act on the silicone.

Lengths in mm, stretch as a fraction (0.1 = 10 %).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import GeometryError

if TYPE_CHECKING:
    from fruitcli.fem.fem_model import FemModel

YARN_BREAK_STRETCH = 0.30
"""DataStretch yarn stretches at most about 30 % (the paper)."""
YARN_MARGIN = 0.05
"""Kept below the yarn's limit for what the model does not see (the stitch tension, the
yarn's own stiffness, mesh error): the default warning level is 0.30 - 0.05 = 0.25."""
DEFAULT_MAX_STRETCH = YARN_BREAK_STRETCH - YARN_MARGIN
DEFAULT_PITCH_MM = 4.0
"""Zig-zag pitch (mm) the warnings quote, and the length over which a track's local
stretch is measured, unless [tracks] zigzag_pitch_mm says otherwise."""
YARN_COLUMNS = [
    "track",
    "axis",
    "index",
    "rest_length_mm",
    "max_stretch_pct",
    "state_of_max",
    "max_local_stretch_pct",
    "state_of_local_max",
]


@dataclass
class Track:
    """One yarn track: its number, section axis ('x' or 'y'), grid index, and centre line
    points (n, 3) mm on the rest surface."""

    track: int
    axis: str
    index: int
    points: np.ndarray


TRACK_FIELDS = ["track", "axis", "index", "point", "x_mm", "y_mm", "z_mm"]


def read_tracks(path: str | Path) -> list[Track]:
    """Tracks from make-tracks' tracks.csv (track, axis, index, point, x_mm, y_mm, z_mm;
    lines starting with # are comments). Any fault: GeometryError naming the file and line."""
    import csv

    path = Path(path)
    if not path.is_file():
        raise GeometryError(
            f"{path}: tracks file not found (make-tracks writes tracks.csv; "
            "run it again, or set [tracks] file)"
        )
    rows: dict[int, list] = {}
    meta: dict[int, tuple[str, int]] = {}
    with open(path, newline="", encoding="utf-8-sig", errors="replace") as fh:
        lines = [
            (n, line) for n, line in enumerate(fh, 1) if line.strip() and not line.startswith("#")
        ]
    if not lines:
        raise GeometryError(f"{path}: no tracks (expected a header {','.join(TRACK_FIELDS)})")
    header = next(csv.reader([lines[0][1]]))
    col = {name.strip(): k for k, name in enumerate(header)}
    if not set(TRACK_FIELDS) <= set(col):
        raise GeometryError(
            f"{path}: line {lines[0][0]}: expected columns "
            f"{','.join(TRACK_FIELDS)}, got {','.join(header)}"
        )
    for n, line in lines[1:]:
        cells = next(csv.reader([line]))
        try:
            v = {f: cells[col[f]].strip() for f in TRACK_FIELDS}
            t, axis, index, point = int(v["track"]), v["axis"], int(v["index"]), int(v["point"])
            xyz = [float(v[f]) for f in ("x_mm", "y_mm", "z_mm")]
        except (IndexError, ValueError):
            raise GeometryError(
                f"{path}: line {n}: expected integers track, index, point, "
                f"an axis and numbers x_mm, y_mm, z_mm, got {line.strip()!r}"
            ) from None
        if axis not in ("x", "y") or not np.all(np.isfinite(xyz)):
            raise GeometryError(
                f"{path}: line {n}: expected axis x or y and finite "
                f"coordinates (mm), got {line.strip()!r}"
            )
        if meta.setdefault(t, (axis, index)) != (axis, index):
            raise GeometryError(f"{path}: line {n}: track {t} changes its axis or index")
        rows.setdefault(t, []).append((point, *xyz))
    if not rows:
        raise GeometryError(f"{path}: no track points")
    out = []
    for t in sorted(rows):
        pts = np.array(sorted(rows[t]))
        if len(pts) < 2 or len(np.unique(pts[:, 0])) < len(pts):
            raise GeometryError(
                f"{path}: track {t}: expected at least 2 points with distinct point numbers"
            )
        if polyline_lengths(pts[:, 1:]) <= 0:
            raise GeometryError(f"{path}: track {t}: zero length (its points coincide)")
        out.append(Track(t, meta[t][0], meta[t][1], pts[:, 1:]))
    return out


def polyline_lengths(points: np.ndarray) -> np.ndarray:
    """Length (mm) of a polyline (n, 3), or of each of (s, n, 3) -> (s,)."""
    return np.linalg.norm(np.diff(points, axis=-2), axis=-1).sum(axis=-1)


def local_stretch(rest_points: np.ndarray, moved: np.ndarray, window_mm: float) -> np.ndarray:
    """Largest stretch (s,) over any piece of the track at least `window_mm` long at rest
    (from a point to the first point that far along it; the whole track when shorter):
    what one zig-zag wave of that pitch must take up. rest_points (n, 3), moved (s, n, 3)."""
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(rest_points, axis=0), axis=1))]
    now = np.concatenate(
        [
            np.zeros((len(moved), 1)),
            np.cumsum(np.linalg.norm(np.diff(moved, axis=1), axis=2), axis=1),
        ],
        axis=1,
    )
    end = np.searchsorted(arc, arc + window_mm)
    ok = end < len(arc)
    if not ok.any():
        return now[:, -1] / arc[-1] - 1.0
    start, end = np.flatnonzero(ok), end[ok]
    return ((now[:, end] - now[:, start]) / (arc[end] - arc[start]) - 1.0).max(axis=1)


def stretch_table(
    tracks: list[Track],
    moved: list[np.ndarray],
    max_stretch: float = DEFAULT_MAX_STRETCH,
    pitch_mm: float = DEFAULT_PITCH_MM,
) -> tuple[list[list], np.ndarray, list[str]]:
    """Rows for YARN_COLUMNS, the whole-track stretch (tracks, s) and the warnings [str]
    of tracks whose largest stretch over one pitch exceeds `max_stretch`, from each
    track's points in every state, moved[k] (s, n, 3) mm."""
    rows, stretch, warnings = [], [], []
    for t, x in zip(tracks, moved, strict=True):
        rest = float(polyline_lengths(t.points))
        s = polyline_lengths(x) / rest - 1.0
        loc = local_stretch(t.points, x, pitch_mm)
        k, m = int(np.argmax(s)), int(np.argmax(loc))
        rows.append(
            [t.track, t.axis, t.index, rest, 100.0 * float(s[k]), k, 100.0 * float(loc[m]), m]
        )
        stretch.append(s)
        if loc[m] > max_stretch:
            warnings.append(
                f"track {t.track} ({t.axis} = const, index {t.index}, {rest:.1f} mm) "
                f"stretches {100 * loc[m]:.1f} % over {pitch_mm:g} mm in state {m} "
                f"({100 * s[k]:.1f} % over its length), more than [tracks] yarn_max_stretch "
                f"{100 * max_stretch:g} %: sew it in a zig-zag of amplitude "
                f"{zigzag_amplitude(float(loc[m]), pitch_mm):.2f} mm at a {pitch_mm:g} mm "
                "pitch ([tracks] zigzag_pitch_mm) for that slack"
            )
    return rows, np.array(stretch).reshape(len(tracks), -1), warnings


def yarn_stretch(
    tracks: list[Track],
    rest_nodes: np.ndarray,
    tets: np.ndarray,
    displacement_mm: np.ndarray,
    max_stretch: float = DEFAULT_MAX_STRETCH,
    pitch_mm: float = DEFAULT_PITCH_MM,
) -> tuple[list[list], np.ndarray, list[str]]:
    """Each track's rest length and stretch in every state, the points following linear
    tets barycentrically (`follow_tracks` uses the model's own elements).

    rest_nodes (n, 3) mm, tets (m, 4), displacement_mm (s, n, 3). Returns (rows for
    YARN_COLUMNS, stretch (tracks, s) fractions, warnings [str]; see `stretch_table`).
    """
    from fruitcli.fem.elements.barycentric import apply, locate

    disp = np.asarray(displacement_mm, float)
    if disp.ndim != 3 or disp.shape[1:] != np.asarray(rest_nodes).shape:
        raise GeometryError(
            f"displacement_mm: expected (states, {len(rest_nodes)}, 3), got {disp.shape}"
        )
    x = np.asarray(rest_nodes, float)[None] + disp
    moved = []
    for t in tracks:
        tet, w, _ = locate(np.asarray(rest_nodes, float), np.asarray(tets), t.points)
        moved.append(apply(x, np.asarray(tets), tet, w))  # (s, n, 3)
    return stretch_table(tracks, moved, max_stretch, pitch_mm)


def follow_tracks(
    model: FemModel,
    tracks: list[Track],
    states_x: np.ndarray,
    max_stretch: float,
    pitch_mm: float,
    off_body: Callable[[np.ndarray, np.ndarray], np.ndarray],
    progress: Callable[[str], None],
    source: str = "the tracks file",
) -> tuple[list, dict]:
    """The tracks through a solved FEM: every point located in the model's corner tets
    at rest and moved with the model's own shape functions (`model.map_points`, quadratic
    on p2, as the taxels). states_x (s, n, 3) mm. `off_body(points, outside)` gives how
    far (mm) each point lies beyond what the mesh's fit to the body's surface explains
    (`outside`: barycentric, from `locate`); points with a positive value are warned
    about in one line through `progress`, naming `source`, and overstretched tracks one
    line each. Returns (rows for YARN_COLUMNS, summary)."""
    from fruitcli.fem.elements.barycentric import locate

    pts = np.concatenate([t.points for t in tracks])
    tet, w, outside = locate(model.rest, model.tets, pts)
    xs = model.map_points(tet, w, states_x)  # (s, p, 3)
    cut = np.cumsum([len(t.points) for t in tracks])[:-1]
    beyond = np.asarray(off_body(pts, outside), float)
    far = [t.track for t, d in zip(tracks, np.split(beyond, cut), strict=True) if d.max() > 0]
    if far:
        progress(
            f"simulate: warning: {len(far)} of {len(tracks)} tracks of {source} (tracks "
            f"{', '.join(map(str, far))}) have points off the body: "
            f"{int((beyond > 0).sum())} of {len(pts)} points, up to {beyond.max():.2f} mm "
            "farther outside the mesh than the surface it meshes; they follow by "
            f"extrapolation (check {source} or [mesh].size_mm)"
        )
    rows, _, warnings = stretch_table(tracks, np.split(xs, cut, axis=1), max_stretch, pitch_mm)
    for msg in warnings:
        progress(f"simulate: warning: {msg}")
    worst = max(rows, key=lambda r: r[6])
    return rows, {
        "tracks": len(rows),
        "max_stretch_pct": round(max(r[4] for r in rows), 3),
        "max_local_stretch_pct": round(worst[6], 3),
        "worst_track": worst[0],
        "state_of_max": worst[7],
        "yarn_max_stretch": max_stretch,
        "zigzag_pitch_mm": pitch_mm,
        "warnings": warnings,
        "tracks_outside_mesh": far,
        "outside_max": round(float(outside.max()), 3),
        "off_body_max_mm": round(float(max(beyond.max(), 0.0)), 3),
    }


def zigzag_amplitude(stretch: float, pitch_mm: float) -> float:
    """Amplitude A (mm, centre to peak) of a triangle-wave zig-zag of pitch `pitch_mm`
    whose length exceeds the straight track's by `stretch` (so that the track can stretch
    that much before the yarn is taut): A = p / 4 sqrt((1 + s)^2 - 1)."""
    s = max(float(stretch), 0.0)
    return 0.25 * pitch_mm * float(np.sqrt((1.0 + s) ** 2 - 1.0))


def write_yarns_csv(path: str | Path, rows: list[list]) -> None:
    """yarns.csv: one row per track (YARN_COLUMNS), units in its header."""
    from fruitcli.fsutil import write_csv

    write_csv(
        path,
        YARN_COLUMNS,
        rows,
        comments=[
            "yarn tracks: rest length on the rest surface (mm), largest stretch of the whole "
            "track over the simulated states (% of the rest length), the state where it "
            "occurs, and the largest stretch over any piece one zig-zag pitch long (%) with "
            "its state (states counted from 0, as in states.npz)",
            "a triangle-wave zig-zag of amplitude A at pitch p gives slack for a stretch of "
            "sqrt(1 + (4 A / p)^2) - 1",
        ],
    )
