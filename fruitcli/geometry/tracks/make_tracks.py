"""make-tracks: artist mesh -> reduced body, carved yarn tracks, taxels (paper III-D, Fig. 6).

The stage in its steps: load the artist mesh, find the faces that bound its inside
(`_bounding_faces`), offset it inwards by the cover (`reduce`), cut the casting piece
above the split plane (`_top_piece`), section it along the grid (`curves`), find the
taxels at the crossings (`taxels`), carve the tracks (`carve`) and write the outputs
(`outputs`). All outputs of one run appear together in the output folder, or none of
them.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import GeometryError
from fruitcli.geometry.mesh import load, winding

if TYPE_CHECKING:
    import manifold3d

    from fruitcli.geometry.mesh.load import Surface
    from fruitcli.geometry.tracks.carve import Carved
    from fruitcli.geometry.tracks.reduce import Inside, Reduced

# artist edges longer than this many distance-grid spacings are split before the offset
MAX_EDGE_PER_GRID = 3.0
# the split adds at most this many times the target triangle count (else edges stay longer)
MAX_SPLIT_FACES_PER_TARGET = 16
CLI_NAMES = {
    "cover_mm": "--cover-mm",
    "faces": "--faces",
    "spacing_x_mm": "--spacing-x-mm",
    "spacing_y_mm": "--spacing-y-mm",
    "origin_mm": "--origin-mm",
    "track_radius_mm": "--track-radius-mm",
    "split_z_mm": "--split-z-mm",
    "fit_mm": "--fit-mm",
    "unit_hint": load.CLI_UNIT_HINT,
}
"""How a `fruit make-tracks` user sets each option (the names in error messages)."""
SCENE_NAMES = {
    "cover_mm": "[tracks].cover_mm",
    "faces": "[tracks].faces",
    "spacing_x_mm": "[grid].spacing_x_mm",
    "spacing_y_mm": "[grid].spacing_y_mm",
    "origin_mm": "[grid].origin_mm",
    "track_radius_mm": "[tracks].track_radius_mm",
    "split_z_mm": "[tracks].split_z_mm",
    "fit_mm": "[geometry].fit_mm",
    "unit_hint": load.SCENE_ARTIST_HINT,
}
"""The same for a scene's make-tracks stage (pass as `make_tracks(..., names=SCENE_NAMES)`)."""


def _surface_line(surf: Surface, dropped: int, w_range: tuple[float, float]) -> str:
    """One line on what the artist surface had and what was done about it."""
    parts = []
    if surf.holes:
        parts.append(
            f"{surf.holes} hole(s) (largest {surf.largest_hole_perimeter_mm:.1f} mm "
            "around) closed by the level set"
        )
    if surf.parts > 1:
        parts.append(f"{surf.parts} parts merged into their union")
    if surf.non_manifold_edges:
        parts.append(f"{surf.non_manifold_edges} non-manifold edges")
    if dropped:
        parts.append(f"{dropped} faces inside the union (or outside it) dropped")
    return (
        f"the surface is not one closed body: {'; '.join(parts)}; winding number from "
        f"{w_range[0]:.2f} to {w_range[1]:.2f}"
    )


def _check_options(
    opt: dict,
    cover_mm: float,
    faces: int,
    spacing_x_mm: float,
    spacing_y_mm: float,
    track_radius_mm: float,
    origin_mm: Sequence[float] | None,
):
    if not cover_mm >= 0:
        raise GeometryError(f"{opt['cover_mm']}: expected a thickness >= 0 mm, got {cover_mm}")
    if faces < 100:
        raise GeometryError(f"{opt['faces']}: expected at least 100 triangles, got {faces}")
    for key, v in (("spacing_x_mm", spacing_x_mm), ("spacing_y_mm", spacing_y_mm)):
        if not v > 0:
            raise GeometryError(f"{opt[key]}: expected a spacing > 0 mm, got {v}")
    if not track_radius_mm > 0:
        raise GeometryError(
            f"{opt['track_radius_mm']}: expected a radius > 0 mm, got {track_radius_mm}"
        )
    half = 0.5 * min(spacing_x_mm, spacing_y_mm)
    if track_radius_mm > half:
        raise GeometryError(
            f"{opt['track_radius_mm']}: {track_radius_mm:g} mm is more than half "
            f"the grid spacing ({half:g} mm); use a smaller radius or larger "
            "spacings"
        )
    if origin_mm is not None and not np.all(np.isfinite(np.asarray(origin_mm, float))):
        raise GeometryError(
            f"{opt['origin_mm']}: expected two finite numbers (mm), got {list(origin_mm)}"
        )


@dataclass
class Laps:
    """Wall and CPU seconds per step, each said as it ends (``laps("load")``)."""

    say: Callable[[str], None]
    times: dict[str, float] = field(default_factory=dict)
    cpu_times: dict[str, float] = field(default_factory=dict)
    clock: list[float] = field(default_factory=lambda: [time.perf_counter(), time.process_time()])

    def __call__(self, step: str) -> None:
        now, cpu = time.perf_counter(), time.process_time()
        self.times[step] = round(now - self.clock[0], 4)
        self.cpu_times[step] = round(cpu - self.clock[1], 4)
        self.clock[:] = [now, cpu]
        self.say(f"{step}: {self.times[step]:.2f} s ({self.cpu_times[step]:.2f} s CPU)")


def _load_artist(
    artist_path: str | Path,
    unit: str | None,
    fit_mm: float | None,
    opt: dict,
    say: Callable[[str], None],
):
    """The artist mesh (`load.Surface`), its repairs and notes said."""
    surf = load.load_mesh(artist_path, unit, opt["unit_hint"], fit_mm, opt["fit_mm"])
    for r in surf.repairs:
        if r.startswith("merged") and Path(artist_path).suffix.lower() == ".stl":
            continue  # STL stores each triangle's corners apart: welding them is normal
        say(f"make-tracks: {r}" if r.startswith("scaled") else f"make-tracks: repaired: {r}")
    for note in surf.notes:
        say(f"make-tracks: {note}")
    return surf


@dataclass
class Bounding:
    """The artist surface made ready for the offset: its long triangles split (dv, df;
    `split_edge` the edge length reached, None: none split, `want_edge` the one asked,
    `split_cap` the triangles allowed), its inside test and the faces dropped because
    they bound nothing."""

    dv: np.ndarray
    df: np.ndarray
    split_edge: float | None
    want_edge: float
    split_cap: int
    inside: Inside
    dropped: int


def _bounding_faces(surf: Surface, faces: int, opt: dict, src: str) -> Bounding:
    """The artist surface split finely enough for the distance grid of a `faces`-triangle
    reduced body, keeping the faces that have the inside on one side only."""
    from fruitcli.geometry.tracks import reduce
    from fruitcli.geometry.tracks.densify import densify
    from fruitcli.memory import require

    av, af = surf.vertices, surf.faces
    points = reduce.grid_points(av, af, faces)
    require(
        points * reduce.GRID_BYTES_PER_POINT,
        f"{opt['faces']} = {faces:,} on {Path(src).name} (a distance grid of {points:.3g} points)",
        GeometryError,
    )
    # long triangles are split so that nearest-vertex distances bound the exact ones closely
    want_edge = MAX_EDGE_PER_GRID * reduce.grid_for_faces(av, af, faces)
    split_cap = len(af) + MAX_SPLIT_FACES_PER_TARGET * faces
    dv, df, split_edge = densify(av, af, want_edge, split_cap)
    # one part, every edge shared by at most two faces: every face bounds the inside (the
    # holes are closed by caps); overlapping parts or non-manifold edges: faces inside the
    # union, or fins outside it, are found by the winding number on both their sides
    one_sheet = surf.parts == 1 and surf.non_manifold_edges == 0
    inside = reduce.Inside(dv, df, all_faces_bound=one_sheet, holes=surf.holes > 0)
    dropped = 0
    if not one_sheet:
        # faces inside the union of overlapping parts (or fins outside it) bound nothing
        bound = winding.boundary_faces(inside.wn, dv, df)
        dropped = int((~bound).sum())
        if not bound.any():
            raise GeometryError(
                f"{src}: the mesh has no inside: no face has the inside on one "
                "side and the outside on the other (an open sheet or a plane); "
                "give it a closed body (close it, or give the sheet a "
                "thickness, in a modeller)"
            )
        used, kf_ = np.unique(df[bound], return_inverse=True)
        dv, df = dv[used], kf_.reshape(-1, 3)
    return Bounding(dv, df, split_edge, want_edge, split_cap, inside, dropped)


def _top_piece(red: Reduced, rv: np.ndarray, split_z_mm: float | None, opt: dict, src: str):
    """(split z in mm, the reduced body's one piece above it: a manifold3d.Manifold);
    `split_z_mm` None: the body's equator."""
    zlo, zhi = float(rv[:, 2].min()), float(rv[:, 2].max())
    split = red.equator_z_mm if split_z_mm is None else float(split_z_mm)
    if not zlo < split < zhi:
        raise GeometryError(
            f"{opt['split_z_mm']}: {split:g} mm is outside the reduced body "
            f"(z from {zlo:.2f} to {zhi:.2f} mm)"
        )
    top = red.body.trim_by_plane((0.0, 0.0, 1.0), split)
    n_top = len(top.decompose())
    if top.is_empty() or n_top != 1:
        raise GeometryError(
            f"{src}: the part above the split plane z = {split:.2f} mm has "
            f"{n_top} pieces (expected one casting piece); set {opt['split_z_mm']}"
        )
    return split, top


def _taxel_rows(tx: dict, ii: np.ndarray, jj: np.ndarray) -> list:
    """taxels.csv's rows (id, i, j, x, y, z, nx, ny, nz), ordered by i then j."""
    order = np.lexsort((jj, ii))
    rows = []
    for t, o in enumerate(order):
        p, n = tx["xyz"][o], tx["normals"][o]
        rows.append([t, int(ii[o]), int(jj[o]), *map(float, p), *map(float, n)])
    return rows


@dataclass
class Options:
    """make-tracks' options, as given (mm; `faces` the reduced body's triangles)."""

    unit: str | None
    cover_mm: float
    faces: int
    spacing_x_mm: float
    spacing_y_mm: float
    origin_mm: object
    track_radius_mm: float
    split_z_mm: float | None
    fit_mm: float | None


def _report(
    o: Options,
    src: str,
    surf: Surface,
    surface: dict,
    b: Bounding,
    red: Reduced,
    rf: np.ndarray,
    tf: np.ndarray,
    top: manifold3d.Manifold,
) -> dict:
    """report.json's first part: the options, the artist surface, the reduction."""
    return {
        "artist": src,
        "unit": o.unit or "mm",
        "fit_mm": o.fit_mm,
        "repairs": surf.repairs,
        "notes": surf.notes,
        "artist_surface": surface,
        "triangles": {
            "artist": int(len(surf.faces)),
            "split": int(len(b.df)),
            "reduced": int(len(rf)),
            "reduced_top": int(len(tf)),
        },
        "cover_mm": float(o.cover_mm),
        "faces_target": int(o.faces),
        "level_set_edge_mm": red.edge_mm,
        "distance_grid_mm": red.grid_mm,
        "dropped_islands": red.dropped_islands,
        "islands": red.islands,
        "filled_pinches_at_mm": red.filled_pinches,
        "split_long_triangles": b.split_edge is not None,
        "split_edge_mm": b.split_edge,
    }


def _report_tracks(
    report: dict,
    o: Options,
    grid: dict,
    rows: list,
    top: manifold3d.Manifold,
    carved: Carved,
    warnings: list[str],
    tx: dict,
    red: Reduced,
):
    """report.json's second part, added to `report`: the split, grid, taxels, genus,
    slivers, warnings and volumes."""
    tracked = carved.tracked
    report["triangles"]["tracked_top"] = int(len(carved.kf))
    report["triangles"]["tracks"] = int(sum(len(f) for _, f in carved.tube_meshes))
    report.update(
        {
            "split_z_automatic": o.split_z_mm is None,
            "grid": grid,
            "track_radius_mm": float(o.track_radius_mm),
            "taxels": len(rows),
            "genus": {
                "reduced_top": int(top.genus()),
                "tracked_top": int(tracked.genus()),
                "tunnels": max(int(tracked.genus()) - int(top.genus()), 0),
            },
            "dropped_slivers_mm3": carved.slivers,
            "warnings": warnings,
            "taxel_curve_mismatch_mm": tx["mismatch_mm"],
            "volume_mm3": {
                "artist": red.inside_volume_mm3,
                "reduced": float(red.body.volume()),
                "reduced_top": float(top.volume()),
                "tracked_top": float(tracked.volume()),
            },
        }
    )


def make_tracks(
    artist_path: str | Path,
    out_dir: str | Path,
    *,
    unit: str | None = None,
    cover_mm: float = 2.0,
    faces: int = 5000,
    spacing_x_mm: float = 16.0,
    spacing_y_mm: float = 12.0,
    origin_mm: Sequence[float] | None = None,
    track_radius_mm: float = 0.6,
    split_z_mm: float | None = None,
    fit_mm: float | None = None,
    progress: Callable[[str], None] | None = None,
    names: dict[str, str] | None = None,
) -> dict:
    """Run the whole stage on `artist_path`, writing into `out_dir`; returns the report dict.
    `names` (default CLI_NAMES; SCENE_NAMES from a scene) names the options in errors."""
    from fruitcli.geometry.mesh.distance import TreeDistance
    from fruitcli.geometry.tracks import curves, outputs, reduce, taxels
    from fruitcli.geometry.tracks.carve import carve

    say = progress or (lambda msg: None)
    opt = names or CLI_NAMES
    src = str(artist_path)
    o = Options(
        unit, cover_mm, faces, spacing_x_mm, spacing_y_mm, origin_mm, track_radius_mm,
        split_z_mm, fit_mm,
    )  # fmt: skip
    _check_options(opt, cover_mm, faces, spacing_x_mm, spacing_y_mm, track_radius_mm, origin_mm)
    laps = Laps(say)
    surf = _load_artist(artist_path, unit, fit_mm, opt, say)
    laps("load")
    b = _bounding_faces(surf, int(faces), opt, src)
    laps("winding")
    dist = TreeDistance(b.dv, b.df)
    red = reduce.reduce_body(
        b.dv, b.df, float(cover_mm), int(faces), src, dist, opt["cover_mm"], b.inside
    )
    rv, rf = reduce.manifold_arrays(red.body)
    surface = {
        **surf.facts(),
        "parts_merged": surf.parts if surf.parts > 1 else 0,
        "faces_dropped_inside_or_outside": b.dropped,
        "winding_number_min": round(red.winding_range[0], 4),
        "winding_number_max": round(red.winding_range[1], 4),
        "inside_volume_mm3": red.inside_volume_mm3,
    }
    if not surf.closed:
        say(f"make-tracks: {_surface_line(surf, b.dropped, red.winding_range)}")
    laps("reduce")
    offset = reduce.offset_error(
        rv, rf, b.dv, b.df, float(cover_mm), dist=dist, caps=b.inside.cap_points
    )
    laps("hausdorff")

    split, top = _top_piece(red, rv, split_z_mm, opt, src)
    _, tf = reduce.manifold_arrays(top)
    # curves and taxels lie on the reduced surface itself (reduced.stl, what the FEM uses):
    # trim_by_plane may re-triangulate the top, so its faces can differ by a fraction of a mm
    x_pieces, y_pieces, x_planes, y_planes = curves.track_curves(
        rv, rf, split, (spacing_x_mm, spacing_y_mm), origin_mm, track_radius_mm, src
    )
    laps("sections")
    tx = taxels.find_taxels(x_pieces, y_pieces, x_planes, y_planes, rv, rf)
    if len(tx["k"]) == 0:
        raise GeometryError(
            f"{src}: the grid misses the shape (no crossing of x- and y-curves "
            f"on the top surface); check {opt['origin_mm']} and the spacings"
        )
    k0, l0 = int(tx["k"].min()), int(tx["l"].min())
    rows = _taxel_rows(tx, tx["k"] - k0, tx["l"] - l0)
    laps("taxels")

    carved = carve(top, x_pieces, y_pieces, k0, l0, track_radius_mm, opt, src)
    warnings = outputs.reduce_warnings(b.split_edge, b.want_edge, b.split_cap, red, cover_mm)
    warnings += outputs.carve_warnings(carved, top, offset, cover_mm, opt)
    for w in warnings:
        say(f"warning: {w}")
    laps("tracks")

    report = _report(o, src, surf, surface, b, red, rf, tf, top)
    report["offset_error"] = offset
    report["split_z_mm"] = split
    grid = {
        "spacing_x_mm": float(spacing_x_mm),
        "spacing_y_mm": float(spacing_y_mm),
        "origin_mm": [float(x_planes[k0]), float(y_planes[l0])],
        "x_planes": len(x_pieces),
        "y_planes": len(y_pieces),
        "curves": len(carved.curves),
    }
    _report_tracks(report, o, grid, rows, top, carved, warnings, tx, red)
    report["times_s"], report["cpu_times_s"] = laps.times, laps.cpu_times
    outputs.write_outputs(out_dir, rv, rf, carved, rows, report, laps, opt)
    return report
