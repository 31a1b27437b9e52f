"""make-tracks' outputs: its warnings, and the files of one run (reduced.stl,
tracked_top.stl, tracks.stl, tracks.csv, taxels.csv, preview.png, report.json), written
together into the output folder or not at all (mm, mm^3)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np

from fruitcli.errors import GeometryError
from fruitcli.geometry.tracks.carve import Carved, change_tracks

if TYPE_CHECKING:
    import manifold3d

    from fruitcli.geometry.tracks.reduce import Reduced

OFFSET_WARN_FRACTION = 0.5
"""Warn when the reduced surface's Hausdorff distance to the ideal offset exceeds this
fraction of the cover thickness (the default Fruit: 0.81 mm against 2 mm)."""
TAXEL_COLUMNS = ["id", "i", "j", "x_mm", "y_mm", "z_mm", "nx", "ny", "nz"]
TRACK_COLUMNS = ["track", "axis", "index", "point", "x_mm", "y_mm", "z_mm"]


class StepTimes(Protocol):
    """The run's step clock (`make_tracks.Laps`): `laps("export")` ends a step; wall and
    CPU seconds per step."""

    times: dict[str, float]
    cpu_times: dict[str, float]

    def __call__(self, step: str) -> None: ...


def reduce_warnings(
    split_edge: float | None, want_edge: float, split_cap: int, red: Reduced, cover_mm: float
) -> list[str]:
    """What the reduction could not do as asked: long triangles split less finely than
    `want_edge` mm (at most `split_cap` triangles), pieces the offset cut off, places
    where the offset touched itself (`red`: a `reduce.Reduced`)."""
    warnings = []
    if split_edge is not None and split_edge > want_edge:
        warnings.append(
            f"long triangles were split to {split_edge:.2f} mm edges, not "
            f"{want_edge:.2f} mm (at most {split_cap} triangles); the offset "
            "may be less accurate (check offset_error)"
        )
    if red.islands:
        big = max(red.islands, key=lambda i: i["volume_mm3"])
        warnings.append(
            f"the {cover_mm:g} mm offset cut off {len(red.islands)} small piece(s) "
            f"of {sum(i['volume_mm3'] for i in red.islands):.3g} mm^3 (the largest "
            f"at {big['at_mm']} mm): a feature there is thinner than twice the "
            "cover; they are not in the reduced body"
        )
    if red.filled_pinches:
        warnings.append(
            f"the {cover_mm:g} mm offset surface touched itself along "
            f"{len(red.filled_pinches)} edge(s) (first at {red.filled_pinches[0]} mm), "
            "where a feature is about twice the cover thick; each was filled with a "
            "capsule so the reduced body is closed"
        )
    return warnings


def carve_warnings(
    carved: Carved, top: manifold3d.Manifold, offset: dict, cover_mm: float, opt: dict
) -> list[str]:
    """What the carving and the offset's accuracy left to check: slivers dropped, tracks
    tunnelling through the piece `top`, the reduced surface far from the ideal offset."""
    warnings = []
    slivers, tracked = carved.slivers, carved.tracked
    if slivers:
        warnings.append(
            f"dropped {len(slivers)} sliver(s) of {sum(slivers):.3g} mm^3 that "
            "tracks along a sharp edge cut off the piece"
        )
    tunnels = int(tracked.genus()) - int(top.genus())
    if tunnels > 0:
        warnings.append(
            f"the tracks tunnel through the piece ({tunnels} new handle(s), genus "
            f"{top.genus()} -> {tracked.genus()}); try another {opt['origin_mm']} "
            f"or a smaller {opt['track_radius_mm']}"
        )
    if offset["hausdorff_mm"] > OFFSET_WARN_FRACTION * float(cover_mm):
        at = ", ".join(f"{x:.1f}" for x in offset["worst_at_mm"])
        warnings.append(
            f"the reduced surface departs from the ideal {cover_mm:g} mm offset by "
            f"up to {offset['hausdorff_mm']:.2f} mm (mean "
            f"{offset['reduced_to_ideal_mean_mm']:.2f} mm, worst at ({at}) mm): "
            f"a feature there is thinner than twice the cover or finer than the "
            f"reduced mesh; raise {opt['faces']} or lower {opt['cover_mm']}"
        )
    return warnings


def _write_stls(
    tmp: Path, rv: np.ndarray, rf: np.ndarray, carved: Carved, report: dict, src: str, opt: dict
) -> None:
    """reduced.stl and tracked_top.stl, each checked to reload as one closed body, and
    tracks.stl (every tube in one mesh)."""
    from fruitcli.geometry.mesh import export

    closed, bodies = export.write_stl(tmp / "reduced.stl", rv, rf)
    if not closed or bodies != 1:
        raise GeometryError(
            f"{src}: reduced.stl does not reload as one closed mesh ("
            f"{'closed' if closed else 'open'}, {bodies} edge-connected "
            f"bodies)"
        )
    closed, bodies = export.write_stl(tmp / "tracked_top.stl", carved.kv, carved.kf)
    if not closed or bodies != 1:
        raise GeometryError(
            f"{src}: the tracked piece does not reload as one closed body ({bodies} "
            f"bodies{'' if closed else ', open'}); {change_tracks(opt)}"
        )
    report["tracked_top_reloads_watertight"] = closed
    report["tracked_top_bodies"] = bodies
    tube_meshes = carved.tube_meshes
    tube_v = np.concatenate([v for v, _ in tube_meshes])
    offs = np.cumsum([0] + [len(v) for v, _ in tube_meshes[:-1]])
    tube_f = np.concatenate([f + o for (_, f), o in zip(tube_meshes, offs, strict=True)])
    export.write_stl(tmp / "tracks.stl", tube_v, tube_f)


def _write_tables(tmp: Path, carved: Carved, rows: list, name: str, grid: dict) -> None:
    """tracks.csv (the curves' points) and taxels.csv (`rows`)."""
    from fruitcli.fsutil import write_csv

    track_rows = [
        [t, axis, idx, n, *map(float, q)]
        for t, ((axis, idx), pts) in enumerate(zip(carved.curve_ids, carved.curves, strict=True))
        for n, q in enumerate(pts)
    ]
    write_csv(
        tmp / "tracks.csv",
        TRACK_COLUMNS,
        track_rows,
        comments=[
            f"yarn track centre lines of {name} on the reduced surface (mm)",
            "track: curve number; axis x: the section x = const of grid index i (index), "
            "axis y: y = const of index j; point: order along the curve",
        ],
    )
    origin = grid["origin_mm"]
    write_csv(
        tmp / "taxels.csv",
        TAXEL_COLUMNS,
        rows,
        comments=[
            f"taxels of {name}: crossings of the track curves on the reduced surface",
            "x_mm, y_mm, z_mm in mm; nx, ny, nz: outward unit normal; i along x, j along y",
            f"grid origin (plane i=0, j=0) {origin[0]:.6f} {origin[1]:.6f} mm; "
            f"spacing {grid['spacing_x_mm']:g} x {grid['spacing_y_mm']:g} mm",
        ],
    )


def write_outputs(
    out_dir: str | Path,
    rv: np.ndarray,
    rf: np.ndarray,
    carved: Carved,
    rows: list,
    report: dict,
    laps: StepTimes,
    opt: dict,
) -> None:
    """Every file of the run into `out_dir`, all or none (`laps`: the run's `Laps`, whose
    export and preview times, and totals, go into report.json)."""
    from fruitcli.fsutil import staged_dir, write_json
    from fruitcli.geometry.tracks.preview import write_preview

    src = report["artist"]
    name = Path(src).name
    with staged_dir(out_dir) as tmp:
        tmp = Path(tmp)
        _write_stls(tmp, rv, rf, carved, report, src, opt)
        _write_tables(tmp, carved, rows, name, report["grid"])
        laps("export")
        write_preview(
            tmp / "preview.png",
            carved.kv,
            carved.kf,
            carved.curves,
            np.array([r[3:6] for r in rows]),
            f"{name}: {len(rows)} taxels, cover {report['cover_mm']:g} mm, "
            f"tracks r = {report['track_radius_mm']:g} mm",
        )
        laps("preview")
        report["times_s"]["total"] = round(sum(laps.times.values()), 4)
        report["cpu_times_s"]["total"] = round(sum(laps.cpu_times.values()), 4)
        write_json(tmp / "report.json", report)
