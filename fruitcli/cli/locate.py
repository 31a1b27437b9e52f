"""`fruit locate`: detect touches in recorded frames and map them to 3D (mm)."""

from __future__ import annotations

import click

from fruitcli.cli.options import (
    Progress,
    baseline_frames_option,
    divide_by_gain_option,
    fruit_errors,
    hovers_option,
    out_option,
    reduced_build_bar,
    skin_table_option,
    states_option,
    taxels_option,
    threshold_option,
)
from fruitcli.sensing.detection.methods import METHODS, method_help


@click.command()
@click.argument("frames", type=click.Path(dir_okay=False))
@taxels_option(required=True)
@states_option(
    "taxels follow the deformation (the recording's chamber pressures, or its meta state)."
)
@click.option(
    "--scene",
    "scene_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Scene whose [board] and [detection] sections to use.",
)
@baseline_frames_option
@threshold_option
@click.option(
    "--method",
    type=click.Choice(list(METHODS)),
    default=None,
    help=method_help() + ".",
)
@click.option(
    "--surface",
    type=click.Path(dir_okay=False),
    default=None,
    help="The body's closed surface at rest (mm), for the scene's [detection].project = surface.",
)
@click.option(
    "--model",
    "model_kind",
    type=click.Choice(["reduced", "full"]),
    default="reduced",
    show_default=True,
    help="For a recording with chamber pressures and a --scene: reduced (each "
    "frame's taxels from the scene's reduced model, built into "
    "out/<scene name>/reduce on first use) or full (the --states path).",
)
@skin_table_option
@hovers_option
@divide_by_gain_option
@out_option("Output folder: touches.csv (and measured.csv for bench recordings).")
def locate(
    frames,
    taxels_csv,
    states_npz,
    scene_path,
    baseline_frames,
    threshold,
    method,
    surface,
    model_kind,
    skin_toml,
    hovers,
    gains_csv,
    out_dir,
) -> None:
    """Detect touches in FRAMES (.npz or MuCa ASCII log) and locate them in 3D.

    Writes OUT/touches.csv: frame,t_s,touch,i,j,x_mm,y_mm,z_mm,peak,height_mm,
    height_err_mm,strength,size_mm,kind (one row per touch or hover; frames index from 0
    including baseline frames; peak in counts; height above the surface in mm from the
    skin's gap law; strength 1 at contact; size the footprint's sigma in mm). An .npz recording is
    read, detected and written in chunks of frames on the CPUs available, so memory stays
    bounded however long it is; touches.csv appears only once complete.
    """
    from fruitcli.scene import load_scene
    from fruitcli.sensing.frames.recording_chunks import has_pressures
    from fruitcli.sensing.stages import LocateFiles, locate_inputs, run_locate

    progress = Progress("[locate] ")
    with fruit_errors():
        scene = load_scene(scene_path) if scene_path else None
        skin_table = None
        if skin_toml is not None:
            from fruitcli.sensing.detection.settings import check_skin_file
            from fruitcli.sensing.skin.heights import skin_with_gap_law

            skin_table = skin_with_gap_law(skin_toml)
            check_skin_file(skin_toml, method or (scene.detection.method if scene else None))
        reduced = None
        if (
            model_kind == "reduced"
            and scene is not None
            and scene.chambers
            and has_pressures(frames, scene.board)
        ):
            from pathlib import Path

            from fruitcli.workflow.reduced_model import ensure_reduced

            reduced = ensure_reduced(
                scene,
                Path("out") / scene.name,
                taxels_csv,
                progress,
                label=f"{scene_path}: --model reduced",
                bar=reduced_build_bar,
            )
        inputs = locate_inputs(
            scene,
            baseline_frames=baseline_frames,
            threshold_counts=threshold,
            method=method,
            hovers=hovers,
            gains_csv=gains_csv,
            skin_table=skin_table,
            reduced=reduced,
        )
        files = LocateFiles(frames, taxels_csv, states_npz, out_dir, surface)
        res = run_locate(inputs, files, progress)
    model = {
        "reduced": "taxels from the reduced model",
        "full": "taxels along the simulated states",
    }.get(res.get("model", ""), "")
    click.echo(
        f"{res['touches']} touches in {res['frames']} frames "
        f"({res['frames_per_s']:.0f} frames/s) -> {res['touches_csv']}"
        + (f"; {model}" if model else ""),
        err=True,
    )
