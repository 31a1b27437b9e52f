"""Yarn stretch along the tracks through the simulated states (paper Sec. III-D).

The paper sews DataStretch yarn along the tracks in a slight zig-zag: the yarn stretches
at most about 30 % and its stiffness should not act on the silicone. Each track's centre
line (on the rest surface) is mapped into the FEM's tets once, at rest, and follows them
barycentrically (as the taxels do); its length in every state against its rest length is
its stretch. The zig-zag that gives that much slack is a triangle wave of amplitude A at
pitch p: it straightens fully when the track stretches by sqrt(1 + (4 A / p)^2) - 1.

Lengths in mm, stretch as a fraction (0.1 = 10 %).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fruitcli.errors import GeometryError

YARN_BREAK_STRETCH = 0.30
"""DataStretch yarn stretches at most about 30 % (the paper)."""
YARN_MARGIN = 0.05
"""Kept below the yarn's limit for what the model does not see (the stitch tension, the
yarn's own stiffness, mesh error): the default warning level is 0.30 - 0.05 = 0.25."""
DEFAULT_MAX_STRETCH = YARN_BREAK_STRETCH - YARN_MARGIN
YARN_COLUMNS = ["track", "axis", "index", "rest_length_mm", "max_stretch_pct",
                "state_of_max"]


@dataclass
class Track:
    """One yarn track: its number, section axis ('x' or 'y'), grid index, and centre line
    points (n, 3) mm on the rest surface."""

    track: int
    axis: str
    index: int
    points: np.ndarray


def read_tracks(path) -> list[Track]:
    """Tracks from make-tracks' tracks.csv (track, axis, index, point, x_mm, y_mm, z_mm)."""
    import csv

    rows: dict[int, list] = {}
    meta: dict[int, tuple[str, int]] = {}
    with open(path, newline="") as fh:
        reader = csv.DictReader(line for line in fh if not line.startswith("#"))
        need = {"track", "axis", "index", "point", "x_mm", "y_mm", "z_mm"}
        if not need <= set(reader.fieldnames or []):
            raise GeometryError(f"{path}: expected columns {', '.join(sorted(need))}")
        try:
            for r in reader:
                t = int(r["track"])
                meta[t] = (r["axis"], int(r["index"]))
                rows.setdefault(t, []).append((int(r["point"]), float(r["x_mm"]),
                                               float(r["y_mm"]), float(r["z_mm"])))
        except ValueError as exc:
            raise GeometryError(f"{path}: line {reader.line_num}: {exc}") from None
    out = []
    for t in sorted(rows):
        pts = np.array(sorted(rows[t]))[:, 1:]
        out.append(Track(t, meta[t][0], meta[t][1], pts))
    return out


def polyline_lengths(points: np.ndarray) -> np.ndarray:
    """Length (mm) of a polyline (n, 3), or of each of (s, n, 3) -> (s,)."""
    return np.linalg.norm(np.diff(points, axis=-2), axis=-1).sum(axis=-1)


def yarn_stretch(tracks: list[Track], rest_nodes: np.ndarray, tets: np.ndarray,
                 displacement_mm: np.ndarray, max_stretch: float = DEFAULT_MAX_STRETCH):
    """Each track's rest length and stretch in every state.

    rest_nodes (n, 3) mm, tets (m, 4), displacement_mm (s, n, 3). Returns (rows for
    YARN_COLUMNS, stretch (tracks, s) fractions, warnings [str] for tracks whose largest
    stretch exceeds `max_stretch`).
    """
    from fruitcli.fem.elements.barycentric import apply, locate

    disp = np.asarray(displacement_mm, float)
    if disp.ndim != 3 or disp.shape[1:] != np.asarray(rest_nodes).shape:
        raise GeometryError(f"displacement_mm: expected (states, {len(rest_nodes)}, 3), got "
                            f"{disp.shape}")
    x = np.asarray(rest_nodes, float)[None] + disp
    rows, stretch, warnings = [], [], []
    for t in tracks:
        tet, w, _ = locate(np.asarray(rest_nodes, float), np.asarray(tets), t.points)
        moved = apply(x, np.asarray(tets), tet, w)            # (s, n, 3)
        rest = float(polyline_lengths(t.points))
        s = polyline_lengths(moved) / rest - 1.0
        k = int(np.argmax(s))
        rows.append([t.track, t.axis, t.index, rest, 100.0 * float(s[k]), k])
        stretch.append(s)
        if s[k] > max_stretch:
            warnings.append(f"track {t.track} ({t.axis} = const, index {t.index}) stretches "
                            f"{100 * s[k]:.1f} % in state {k}, more than "
                            f"{100 * max_stretch:.0f} %; sew it in a zig-zag of amplitude "
                            f"{zigzag_amplitude(float(s[k]), 4.0):.2f} mm at a 4 mm pitch")
    return rows, np.array(stretch).reshape(len(tracks), -1), warnings


def zigzag_amplitude(stretch: float, pitch_mm: float) -> float:
    """Amplitude A (mm, centre to peak) of a triangle-wave zig-zag of pitch `pitch_mm`
    whose length exceeds the straight track's by `stretch` (so that the track can stretch
    that much before the yarn is taut): A = p / 4 sqrt((1 + s)^2 - 1)."""
    s = max(float(stretch), 0.0)
    return 0.25 * pitch_mm * float(np.sqrt((1.0 + s) ** 2 - 1.0))


def write_yarns_csv(path, rows) -> None:
    """yarns.csv: one row per track (YARN_COLUMNS), units in its header."""
    from fruitcli.fsutil import write_csv

    write_csv(path, YARN_COLUMNS, rows, comments=[
        "yarn tracks: rest length on the rest surface (mm), largest stretch over the "
        "simulated states (% of the rest length), the state where it occurs",
        "a triangle-wave zig-zag of amplitude A at pitch p gives slack for a stretch of "
        "sqrt(1 + (4 A / p)^2) - 1"])
