"""make-tracks: artist mesh -> reduced body, carved yarn tracks, taxels (paper III-D, Fig. 6).

All outputs of one run appear together in the output folder, or none of them.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from fruitcli.errors import GeometryError
from fruitcli.geometry.mesh import load, winding

# a face takes part in the track curves when its normal's z component exceeds this
UP_NZ_MIN = 0.05
# pieces of section curves shorter than this many track radii are not carved
MIN_PIECE_RADII = 4.0
# gaps in a track curve's upward-facing part shorter than this many track radii are bridged
MAX_GAP_RADII = 6.0
# artist edges longer than this many distance-grid spacings are split before the offset
MAX_EDGE_PER_GRID = 3.0
# the split adds at most this many times the target triangle count (else edges stay longer)
MAX_SPLIT_FACES_PER_TARGET = 16
# track curves keep this many track radii above the split plane (no tube cuts the cap)
SPLIT_CLEARANCE_RADII = 2.0
# the tracked piece may lose at most this fraction of its volume to the tubes
MAX_TRACK_VOLUME_FRACTION = 0.25
# bodies cut off by the tubes (along a sharp edge) are dropped below this fraction of the
# piece's volume, in total; larger ones make the carving fail
MAX_SLIVER_VOLUME_FRACTION = 1e-3
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
TAXEL_COLUMNS = ["id", "i", "j", "x_mm", "y_mm", "z_mm", "nx", "ny", "nz"]
TRACK_COLUMNS = ["track", "axis", "index", "point", "x_mm", "y_mm", "z_mm"]


def _surface_line(surf, dropped: int, w_range) -> str:
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


def _change_tracks(opt: dict) -> str:
    """What to change when the tracks cut the piece apart (`opt`: CLI_NAMES or SCENE_NAMES)."""
    return (
        f"try a smaller {opt['track_radius_mm']}, or move the grid lines ({opt['origin_mm']}, "
        f"{opt['spacing_x_mm']}, {opt['spacing_y_mm']})"
    )


def _check_options(opt, cover_mm, faces, spacing_x_mm, spacing_y_mm, track_radius_mm):
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


def _planes(lo: float, hi: float, spacing: float, origin: float | None) -> dict[int, float]:
    """Plane index -> coordinate for the planes origin + k * spacing inside (lo, hi)."""
    if origin is None:
        n = int(np.floor((hi - lo) / spacing))
        origin = 0.5 * (lo + hi) - 0.5 * n * spacing
    k0, k1 = int(np.ceil((lo - origin) / spacing)), int(np.floor((hi - origin) / spacing))
    return {k: origin + k * spacing for k in range(k0, k1 + 1)}


def _upward_nz(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Per face, the smaller z component of its unit normal and of the area-weighted mean
    normal of the faces sharing a vertex with it.

    A level-set wall is a sawtooth of facets tilted alternately up and down by a few
    degrees; face by face about half of a vertical wall looks upward-facing, and bridging
    the gaps between those faces would run tracks down the wall. The neighbourhood mean
    cancels the sawtooth; taking the smaller value only ever drops faces from the mask.
    """
    tri = vertices[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    vn = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(vn, faces[:, k], fn)
    out = []
    for n in (fn, vn[faces].sum(axis=1)):
        out.append(n[:, 2] / np.maximum(np.linalg.norm(n, axis=1), 1e-300))
    return np.minimum(*out)


def _drop_slivers(piece, top_volume: float):
    """Drop the small bodies that tubes running along a sharp edge cut off the piece.

    Returns (the piece without them, [their volumes in mm^3]).
    """
    import manifold3d

    if piece.is_empty() or piece.status() != manifold3d.Error.NoError:
        return piece, []
    parts = sorted(piece.decompose(), key=lambda m: -m.volume())
    small = [float(p.volume()) for p in parts[1:]]
    if not small or sum(small) >= MAX_SLIVER_VOLUME_FRACTION * top_volume:
        return piece, []
    return parts[0], small


def _drop_edge_slivers(vertices: np.ndarray, faces: np.ndarray, top_volume: float):
    """Faces of the largest edge-connected shell, and the volumes (mm^3) of the others.

    manifold3d counts shells touching at a vertex as one body, and welding for a float32
    STL can remove the zero-volume fin that joined them; an STL reader sees separate bodies.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, edge_id = np.unique(e[:, 0] * len(vertices) + e[:, 1], return_inverse=True)
    owner = np.tile(np.arange(len(faces)), 3)
    graph = coo_matrix(
        (np.ones(len(owner)), (owner, edge_id.ravel() + len(faces))),
        shape=(len(faces) + edge_id.max() + 1,) * 2,
    )
    n, labels = connected_components(graph, directed=False)
    labels = labels[: len(faces)]
    if len(np.unique(labels)) == 1:
        return faces, []
    tri = vertices[faces]
    six_vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
    vol = np.bincount(labels, six_vol, minlength=n) / 6.0
    big = int(np.argmax(vol))
    others = [float(v) for k, v in enumerate(vol) if k != big and np.any(labels == k)]
    if sum(abs(v) for v in others) >= MAX_SLIVER_VOLUME_FRACTION * top_volume:
        return faces, []
    return faces[labels == big], others


OFFSET_WARN_FRACTION = 0.5
"""Warn when the reduced surface's Hausdorff distance to the ideal offset exceeds this
fraction of the cover thickness (the default Fruit: 0.81 mm against 2 mm)."""


def make_tracks(
    artist_path,
    out_dir,
    *,
    unit=None,
    cover_mm=2.0,
    faces=5000,
    spacing_x_mm=16.0,
    spacing_y_mm=12.0,
    origin_mm=None,
    track_radius_mm=0.6,
    split_z_mm=None,
    fit_mm=None,
    progress=None,
    names=None,
) -> dict:
    """Run the whole stage on `artist_path`, writing into `out_dir`; returns the report dict.
    `names` (default CLI_NAMES; SCENE_NAMES from a scene) names the options in errors."""
    import manifold3d

    from fruitcli.fsutil import staged_dir, write_csv, write_json
    from fruitcli.geometry.mesh import export
    from fruitcli.geometry.mesh.distance import TreeDistance
    from fruitcli.geometry.tracks import reduce, sections, taxels, tubes
    from fruitcli.geometry.tracks.preview import write_preview

    say = progress or (lambda msg: None)
    opt = names or CLI_NAMES
    src = str(artist_path)
    _check_options(opt, cover_mm, faces, spacing_x_mm, spacing_y_mm, track_radius_mm)
    if origin_mm is not None and not np.all(np.isfinite(np.asarray(origin_mm, float))):
        raise GeometryError(
            f"{opt['origin_mm']}: expected two finite numbers (mm), got {list(origin_mm)}"
        )
    times: dict[str, float] = {}
    cpu_times: dict[str, float] = {}
    clock = [time.perf_counter(), time.process_time()]

    def lap(step):
        now, cpu = time.perf_counter(), time.process_time()
        times[step] = round(now - clock[0], 4)
        cpu_times[step] = round(cpu - clock[1], 4)
        clock[:] = [now, cpu]
        say(f"{step}: {times[step]:.2f} s ({cpu_times[step]:.2f} s CPU)")

    surf = load.load_mesh(artist_path, unit, opt["unit_hint"], fit_mm, opt["fit_mm"])
    repairs = surf.repairs
    for r in repairs:
        if r.startswith("merged") and Path(artist_path).suffix.lower() == ".stl":
            continue  # STL stores each triangle's corners apart: welding them is normal
        say(f"make-tracks: {r}" if r.startswith("scaled") else f"make-tracks: repaired: {r}")
    for note in surf.notes:
        say(f"make-tracks: {note}")
    av, af = surf.vertices, surf.faces
    lap("load")

    from fruitcli.memory import require

    points = reduce.grid_points(av, af, int(faces))
    require(
        points * reduce.GRID_BYTES_PER_POINT,
        f"{opt['faces']} = {int(faces):,} on {Path(src).name} (a distance grid of "
        f"{points:.3g} points)",
        GeometryError,
    )
    # long triangles are split so that nearest-vertex distances bound the exact ones closely
    want_edge = MAX_EDGE_PER_GRID * reduce.grid_for_faces(av, af, int(faces))
    split_cap = len(af) + MAX_SPLIT_FACES_PER_TARGET * int(faces)
    dv, df, split_edge = reduce.densify(av, af, want_edge, split_cap)
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
    lap("winding")
    dist = TreeDistance(dv, df)
    red = reduce.reduce_body(
        dv, df, float(cover_mm), int(faces), src, dist, opt["cover_mm"], inside
    )
    rv, rf = reduce.manifold_arrays(red.body)
    surface = {
        **surf.facts(),
        "parts_merged": surf.parts if surf.parts > 1 else 0,
        "faces_dropped_inside_or_outside": dropped,
        "winding_number_min": round(red.winding_range[0], 4),
        "winding_number_max": round(red.winding_range[1], 4),
        "inside_volume_mm3": red.inside_volume_mm3,
    }
    if not surf.closed:
        say(f"make-tracks: {_surface_line(surf, dropped, red.winding_range)}")
    lap("reduce")
    offset = reduce.offset_error(rv, rf, dv, df, float(cover_mm), dist=dist, caps=inside.cap_points)
    lap("hausdorff")

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
    _, tf = reduce.manifold_arrays(top)
    # curves and taxels lie on the reduced surface itself (reduced.stl, what the FEM uses):
    # trim_by_plane may re-triangulate the top, so its faces can differ by a fraction of a mm
    sv, sf = rv, rf
    tri = sv[sf]
    up = (_upward_nz(sv, sf) > UP_NZ_MIN) & (
        tri[:, :, 2].min(axis=1) > split + SPLIT_CLEARANCE_RADII * track_radius_mm
    )
    if not up.any():
        raise GeometryError(f"{src}: no upward-facing surface above z = {split:.2f} mm")
    upv = sv[np.unique(sf[up])]
    ox, oy = (None, None) if origin_mm is None else (float(origin_mm[0]), float(origin_mm[1]))
    x_planes = _planes(upv[:, 0].min(), upv[:, 0].max(), spacing_x_mm, ox)
    y_planes = _planes(upv[:, 1].min(), upv[:, 1].max(), spacing_y_mm, oy)
    min_len = MIN_PIECE_RADII * track_radius_mm

    max_gap = MAX_GAP_RADII * track_radius_mm
    below = tri[:, :, 2].max(axis=1) < split  # sections stay on the top half

    def cut(axis, planes):
        out = {}
        for k, value in planes.items():
            ps = [
                q
                for p in sections.section_pieces(sv, sf, axis, value, ~below)
                for q in sections.masked_runs(p, up[p.faces], max_gap, min_len)
            ]
            if ps:
                out[k] = ps
        return out

    x_pieces, y_pieces = cut(0, x_planes), cut(1, y_planes)
    lap("sections")
    tx = taxels.find_taxels(x_pieces, y_pieces, x_planes, y_planes, sv, sf)
    if len(tx["k"]) == 0:
        raise GeometryError(
            f"{src}: the grid misses the shape (no crossing of x- and y-curves "
            f"on the top surface); check {opt['origin_mm']} and the spacings"
        )
    k0, l0 = int(tx["k"].min()), int(tx["l"].min())
    ii, jj = tx["k"] - k0, tx["l"] - l0
    origin_used = [float(x_planes[k0]), float(y_planes[l0])]
    lap("taxels")

    curves = [p.points for d in (x_pieces, y_pieces) for k in sorted(d) for p in d[k]]
    closed = [p.closed for d in (x_pieces, y_pieces) for k in sorted(d) for p in d[k]]
    # each curve's axis (x: a plane x = const, index i; y: y = const, index j)
    curve_ids = [
        (axis, k - k_min)
        for axis, d, k_min in (("x", x_pieces, k0), ("y", y_pieces, l0))
        for k in sorted(d)
        for _ in d[k]
    ]
    tube_meshes = []
    for pts, cl in zip(curves, closed, strict=True):
        for line in tubes.track_polylines(pts, cl):
            tube_meshes.append(tubes.tube_arrays(line, track_radius_mm))
    tube_manifolds = [load.to_manifold(v, f) for v, f in tube_meshes]
    bad = [m.status().name for m in tube_manifolds if m.status() != manifold3d.Error.NoError]
    if bad:
        raise GeometryError(
            f"{src}: {len(bad)} track tube(s) are not valid solids ({bad[0]}); "
            f"try a smaller {opt['track_radius_mm']}"
        )
    tracked = manifold3d.Manifold.batch_boolean([top, *tube_manifolds], manifold3d.OpType.Subtract)
    tracked, slivers = _drop_slivers(tracked, top.volume())
    lost = 1.0 - tracked.volume() / top.volume()
    n_tracked = len(tracked.decompose()) if not tracked.is_empty() else 0
    if (
        tracked.status() != manifold3d.Error.NoError
        or n_tracked != 1
        or not 0 < lost < MAX_TRACK_VOLUME_FRACTION
    ):
        raise GeometryError(
            f"{src}: carving the tracks gave an invalid piece ({n_tracked} "
            f"bodies, genus {tracked.genus()}, {100 * lost:.1f} % removed); "
            f"{_change_tracks(opt)}"
        )
    kv, kf = export.weld_float32(*reduce.manifold_arrays(tracked))
    kf, more = _drop_edge_slivers(kv, kf, top.volume())
    slivers += more
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
    for w in warnings:
        say(f"warning: {w}")
    lap("tracks")

    order = np.lexsort((jj, ii))
    rows = []
    for t, o in enumerate(order):
        p, n = tx["xyz"][o], tx["normals"][o]
        rows.append([t, int(ii[o]), int(jj[o]), *map(float, p), *map(float, n)])
    report = {
        "artist": src,
        "unit": unit or "mm",
        "fit_mm": fit_mm,
        "repairs": repairs,
        "notes": surf.notes,
        "artist_surface": surface,
        "triangles": {
            "artist": int(len(af)),
            "split": int(len(df)),
            "reduced": int(len(rf)),
            "reduced_top": int(len(tf)),
            "tracked_top": int(len(kf)),
            "tracks": int(sum(len(f) for _, f in tube_meshes)),
        },
        "cover_mm": float(cover_mm),
        "faces_target": int(faces),
        "level_set_edge_mm": red.edge_mm,
        "distance_grid_mm": red.grid_mm,
        "dropped_islands": red.dropped_islands,
        "islands": red.islands,
        "filled_pinches_at_mm": red.filled_pinches,
        "split_long_triangles": split_edge is not None,
        "split_edge_mm": split_edge,
        "offset_error": offset,
        "split_z_mm": split,
        "split_z_automatic": split_z_mm is None,
        "grid": {
            "spacing_x_mm": float(spacing_x_mm),
            "spacing_y_mm": float(spacing_y_mm),
            "origin_mm": origin_used,
            "x_planes": len(x_pieces),
            "y_planes": len(y_pieces),
            "curves": len(curves),
        },
        "track_radius_mm": float(track_radius_mm),
        "taxels": len(rows),
        "genus": {
            "reduced_top": int(top.genus()),
            "tracked_top": int(tracked.genus()),
            "tunnels": max(tunnels, 0),
        },
        "dropped_slivers_mm3": slivers,
        "warnings": warnings,
        "taxel_curve_mismatch_mm": tx["mismatch_mm"],
        "volume_mm3": {
            "artist": red.inside_volume_mm3,
            "reduced": float(red.body.volume()),
            "reduced_top": float(top.volume()),
            "tracked_top": float(tracked.volume()),
        },
        "times_s": times,
        "cpu_times_s": cpu_times,
    }
    with staged_dir(out_dir) as tmp:
        tmp = Path(tmp)
        closed, bodies = export.write_stl(tmp / "reduced.stl", rv, rf)
        if not closed or bodies != 1:
            raise GeometryError(
                f"{src}: reduced.stl does not reload as one closed mesh ("
                f"{'closed' if closed else 'open'}, {bodies} edge-connected "
                f"bodies)"
            )
        closed, bodies = export.write_stl(tmp / "tracked_top.stl", kv, kf)
        if not closed or bodies != 1:
            raise GeometryError(
                f"{src}: the tracked piece does not reload as one closed body ({bodies} "
                f"bodies{'' if closed else ', open'}); {_change_tracks(opt)}"
            )
        report["tracked_top_reloads_watertight"] = closed
        report["tracked_top_bodies"] = bodies
        tube_v = np.concatenate([v for v, _ in tube_meshes])
        offs = np.cumsum([0] + [len(v) for v, _ in tube_meshes[:-1]])
        tube_f = np.concatenate([f + o for (_, f), o in zip(tube_meshes, offs, strict=True)])
        export.write_stl(tmp / "tracks.stl", tube_v, tube_f)
        track_rows = [
            [t, axis, idx, n, *map(float, q)]
            for t, ((axis, idx), pts) in enumerate(zip(curve_ids, curves, strict=True))
            for n, q in enumerate(pts)
        ]
        write_csv(
            tmp / "tracks.csv",
            TRACK_COLUMNS,
            track_rows,
            comments=[
                f"yarn track centre lines of {Path(src).name} on the reduced surface (mm)",
                "track: curve number; axis x: the section x = const of grid index i (index), "
                "axis y: y = const of index j; point: order along the curve",
            ],
        )
        write_csv(
            tmp / "taxels.csv",
            TAXEL_COLUMNS,
            rows,
            comments=[
                f"taxels of {Path(src).name}: crossings of the track curves on the reduced surface",
                "x_mm, y_mm, z_mm in mm; nx, ny, nz: outward unit normal; i along x, j along y",
                f"grid origin (plane i=0, j=0) {origin_used[0]:.6f} {origin_used[1]:.6f} mm; "
                f"spacing {spacing_x_mm:g} x {spacing_y_mm:g} mm",
            ],
        )
        lap("export")
        write_preview(
            tmp / "preview.png",
            kv,
            kf,
            curves,
            np.array([r[3:6] for r in rows]),
            f"{Path(src).name}: {len(rows)} taxels, cover {cover_mm:g} mm, "
            f"tracks r = {track_radius_mm:g} mm",
        )
        lap("preview")
        report["times_s"]["total"] = round(sum(times.values()), 4)
        report["cpu_times_s"]["total"] = round(sum(cpu_times.values()), 4)
        write_json(tmp / "report.json", report)
    return report
