"""The geometry stages: make-artist (the default fruit's mesh), make-tracks (reduce the
artist mesh, carve the yarn tracks, export the taxels) and pad-grid (a flat pad's taxels
and grid lines). The heavy modules are imported only when a stage runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from fruitcli.workflow.stage_paths import GEOMETRY_KIND, YARN_KEYS, geometry_kind, no_inputs
from fruitcli.workflow.stage_types import Stage

if TYPE_CHECKING:
    from fruitcli.scene import Scene
    from fruitcli.workflow.stage_types import Context


# ----------------------------------------------------------------------------- make-artist
def _artist_needed(scene: Scene):
    geo = scene.geometry
    if geo.artist is None:
        kind = geometry_kind(scene)
        return False, (
            "no geometry: evaluation only" if kind == "none" else f"no artist mesh: {kind} geometry"
        )
    if not geo.generate_artist:
        return False, "artist mesh given"
    return True, "default fruit generated on first use"


def _artist_run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.geometry.artist import write_artist

    out_dir.mkdir(parents=True, exist_ok=True)
    artist = scene.geometry.artist
    assert artist is not None  # `_artist_needed`
    if Path(artist).exists():  # "if missing": a mesh at `artist` is the user's, kept
        ctx.progress(f"{artist}: exists, kept (generate_artist writes it only when missing)")
        return {"artist": str(artist), "generated": False}
    write_artist(artist)
    return {"artist": str(artist), "generated": True}


# ----------------------------------------------------------------------------- make-tracks
def _tracks_needed(scene: Scene):
    kind = geometry_kind(scene)
    if kind == "artist":
        return True, "artist mesh: reduce, carve yarn tracks, export taxels"
    if kind == "pad":
        return False, "flat pad: no artist mesh, no tracks"
    if kind == "solid":
        return False, "solid given: used as is, no reduction or tracks"
    return False, "no geometry: evaluation only"


def _tracks_run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.geometry.tracks.make_tracks import SCENE_NAMES, make_tracks

    geo, tr, grid = scene.geometry, scene.tracks, scene.grid
    assert geo.artist is not None  # `_tracks_needed`
    report = make_tracks(
        geo.artist,
        out_dir,
        unit=geo.unit,
        cover_mm=tr.cover_mm,
        faces=tr.faces,
        spacing_x_mm=grid.spacing_x_mm,
        spacing_y_mm=grid.spacing_y_mm,
        origin_mm=grid.origin_mm,
        track_radius_mm=tr.track_radius_mm,
        split_z_mm=tr.split_z_mm,
        fit_mm=geo.fit_mm,
        progress=ctx.progress,
        names=SCENE_NAMES,
    )
    return {"taxels": report["taxels"], "hausdorff_mm": report["offset_error"]["hausdorff_mm"]}


# ----------------------------------------------------------------------------- pad-grid
def _pad_needed(scene: Scene):
    if geometry_kind(scene) != "pad":
        return False, "not a flat pad"
    if scene.grid.taxels is not None:
        return False, "taxels given"
    return True, "flat pad: taxels on a regular grid on its top face"


def _pad_run(scene: Scene, ctx: Context, out_dir: Path):
    from fruitcli.geometry.padgrid import check_pad_size, write_pad_taxels, write_pad_tracks

    grid = scene.grid
    assert scene.geometry.pad_size_mm is not None  # `_pad_needed`
    args = (scene.geometry.pad_size_mm, grid.count or [4, 4], grid.spacing_x_mm, grid.spacing_y_mm)
    check_pad_size(args[0], args[1], scene.path.name)
    n = write_pad_taxels(out_dir / "taxels.csv", *args)
    return {"taxels": n, "tracks": write_pad_tracks(out_dir / "tracks.csv", *args)}


# ----------------------------------------------------------------------------- the table's entries
MAKE_ARTIST_STAGE = Stage(
    "make-artist",
    [],
    "fruitcli.geometry.artist",
    _artist_needed,
    # nothing but the code: the mesh it writes is the same wherever it goes, so a scene
    # copied elsewhere (`fruit demo`'s OUT/scenes/) keeps every later stage's hash; a
    # path without the file fails the outputs check and the stage runs again
    no_inputs,
    _artist_run,
    lambda s: [str(s.geometry.artist)],
    reads=("geometry.generate_artist",),
    decides=GEOMETRY_KIND,
    derived=("geometry.artist",),
)


MAKE_TRACKS_STAGE = Stage(
    "make-tracks",
    ["make-artist"],
    "fruitcli.geometry.tracks.make_tracks",
    _tracks_needed,
    no_inputs,
    _tracks_run,
    lambda s: [
        "reduced.stl",
        "tracked_top.stl",
        "tracks.stl",
        "taxels.csv",
        "tracks.csv",
        "report.json",
        "preview.png",
    ],
    reads=(
        "geometry.artist",
        "geometry.unit",
        "geometry.fit_mm",
        "tracks",
        "grid.spacing_x_mm",
        "grid.spacing_y_mm",
        "grid.origin_mm",
    ),
    minus=YARN_KEYS,
    decides=GEOMETRY_KIND,
)


PAD_GRID_STAGE = Stage(
    "pad-grid",
    [],
    "fruitcli.geometry.padgrid",
    _pad_needed,
    no_inputs,
    _pad_run,
    lambda s: ["taxels.csv", "tracks.csv"],
    reads=("geometry.pad_size_mm", "grid"),
    minus=("grid.taxels",),
    decides=(*GEOMETRY_KIND, "grid.taxels"),
)
