"""Where a scene's stages find their inputs (the taxels, the body's surface, the tracks,
the FEM states, the reduced model, the crossing's table: each a file of the scene or of
an upstream stage's folder) and the groups of scene keys several stages read.
"""

from __future__ import annotations

from pathlib import Path

from fruitcli.errors import FruitError
from fruitcli.scene import Scene, has_deformation
from fruitcli.sensing.skin.models import SKIN_MODELS
from fruitcli.workflow.stage_types import Context


def geometry_kind(scene: Scene) -> str:
    """What [geometry] gives: "artist", "solid", "pad" or "none"."""
    geo = scene.geometry
    if geo.artist is not None:
        return "artist"
    if geo.solid is not None:
        return "solid"
    if geo.pad_size_mm is not None:
        return "pad"
    return "none"


def taxels_path(scene: Scene, ctx: Context) -> Path | None:
    """Where this scene's taxel table comes from."""
    if scene.grid.taxels is not None:
        return scene.grid.taxels
    kind = geometry_kind(scene)
    if kind == "artist":
        return ctx.dir("make-tracks") / "taxels.csv"
    if kind == "pad":
        return ctx.dir("pad-grid") / "taxels.csv"
    return None


def required_taxels_path(scene: Scene, ctx: Context) -> Path:
    """`taxels_path` for a stage that cannot run without taxels."""
    path = taxels_path(scene, ctx)
    if path is None:
        raise FruitError(
            f"{scene.path.name}: no taxels: a [geometry].solid scene takes them from "
            "[grid].taxels (a CSV of id,i,j,x_mm,y_mm,z_mm)"
        )
    return path


def solid_path(scene: Scene, ctx: Context) -> Path | None:
    kind = geometry_kind(scene)
    if kind == "artist":
        return ctx.dir("make-tracks") / "reduced.stl"
    if kind == "solid":
        return scene.geometry.solid
    return None


def _pad_tracks(scene: Scene) -> bool:
    """Whether pad-grid writes the taxels and so the pad's grid lines (tracks.csv)."""
    return geometry_kind(scene) == "pad" and scene.grid.taxels is None


def has_tracks(scene: Scene) -> bool:
    return scene.tracks.file is not None or geometry_kind(scene) == "artist" or _pad_tracks(scene)


def tracks_path(scene: Scene, ctx: Context) -> Path | None:
    """Where this scene's yarn track centre lines come from ([tracks] file, or the
    tracks.csv of make-tracks or pad-grid), or None: no yarns.csv."""
    if scene.tracks.file is not None:
        return scene.tracks.file
    if _pad_tracks(scene):
        return ctx.dir("pad-grid") / "tracks.csv"
    return ctx.dir("make-tracks") / "tracks.csv" if has_tracks(scene) else None


YARN_KEYS = ("tracks.yarn_max_stretch", "tracks.zigzag_pitch_mm", "tracks.file")
"""[tracks] keys read by simulate (yarns.csv), not by make-tracks."""
GEOMETRY_KIND = ("geometry.artist", "geometry.solid", "geometry.pad_size_mm")
"""The keys `geometry_kind` reads."""
DEFORMS = ("actuation", "fixed", "jig", "gravity", "material.density_kg_m3")
"""The keys `has_deformation` reads (whether states.npz exists)."""


def no_inputs(scene: Scene, ctx: Context) -> dict:
    """A stage whose hash is its declared scene keys and upstream hashes alone."""
    return {}


def states_path(scene: Scene, ctx: Context) -> Path | None:
    return ctx.dir("simulate") / "states.npz" if has_deformation(scene) else None


def indenters(scene: Scene) -> list[str]:
    return list(scene.bench.indenters)


def reduced_path(scene: Scene, ctx: Context) -> Path:
    return ctx.dir("reduce") / "reduced.npz"


def electrostatic(scene: Scene) -> bool:
    """Whether the scene's skin is the computed crossing's (`skin.models.SkinModel.computed`)."""
    return SKIN_MODELS[scene.skin.model].computed


def crossing_dir(scene: Scene, ctx: Context) -> Path | None:
    """The skin stage's folder (crossing.npz, summary.json) for an electrostatic skin."""
    return ctx.dir("skin") if electrostatic(scene) else None
