"""`run_locate` called the way the tests speak of it: a scene (or None), the recording,
taxels, states and output folder, and the command's options; the stage's typed inputs
(`locate_inputs`, `LocateFiles`) are built here as a stage builds them."""

from __future__ import annotations

from fruitcli.sensing.detection.frames_to_touches import CHUNK_FRAMES
from fruitcli.sensing.stages import LocateFiles, locate_inputs, run_locate


def locate_scene(
    scene,
    frames,
    taxels,
    states,
    out_dir,
    progress=None,
    *,
    surface_path=None,
    surface_unit: str = "mm",
    chunk_frames: int = CHUNK_FRAMES,
    workers: int | None = None,
    **options,
):
    """`run_locate` of `scene` with `options` (`locate_inputs`'s keywords)."""
    files = LocateFiles(frames, taxels, states, out_dir, surface_path, surface_unit)
    return run_locate(locate_inputs(scene, **options), files, progress, chunk_frames, workers)
