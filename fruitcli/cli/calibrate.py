"""`fruit calibrate`: fit the skin's forward model to a bench recording (mm, counts)."""

from __future__ import annotations

import click

from fruitcli.cli.options import Progress, fruit_errors, out_option, taxels_option
from fruitcli.workflow.scene_outputs import scene_products


@click.command()
@click.argument("frames", type=click.Path(dir_okay=False))
@click.option(
    "--truth",
    "truth_csv",
    required=True,
    type=click.Path(dir_okay=False),
    help="truth.csv of the same bench run (sample,x_mm,y_mm,z_mm, model mm).",
)
@click.option(
    "--scene",
    "scene_path",
    required=True,
    type=click.Path(dir_okay=False),
    help="Scene whose [board] and taxels the recording used.",
)
@taxels_option()
@click.option("--indenter", default=None, help="Indenter of the recording (default: its meta).")
@out_option("Output folder: skin.toml ([skin] table), gains.csv, calibration.json.")
def calibrate(frames, truth_csv, scene_path, taxels_csv, indenter, out_dir) -> None:
    """Fit footprint width, activation at contact, gap decay, per-taxel gains and noise to
    a bench recording (FRAMES: frames.npz of `fruit bench`, virtual or --printer).

    With the scene's [skin] model = "electrostatic": the crossing table's counts per fF
    (the table from the scene's skin stage), per-taxel gains and noise instead."""
    from fruitcli.errors import FrameError
    from fruitcli.scene import load_scene
    from fruitcli.sensing.inputs_stage import calibrate_inputs
    from fruitcli.sensing.skin.calibrate import run_calibrate
    from fruitcli.workflow.scene_outputs import crossing_response

    progress = Progress("[calibrate] ")
    with fruit_errors():
        scene = load_scene(scene_path)
        taxels = taxels_csv or scene.grid.taxels or scene_products(scene)[0]
        if taxels is None:
            raise FrameError(f"{scene_path}: no taxels: give --taxels or [grid].taxels")
        response = crossing_response(scene, progress=progress)
        inputs = calibrate_inputs(scene)
        res = run_calibrate(
            inputs, frames, truth_csv, taxels, out_dir, indenter, progress, response
        )
    fitted = (
        f"footprint sigma {res['footprint_sigma_mm']:.2f} mm, contact "
        f"{res['contact_counts']:.1f} counts, gap decay {res['gap_decay_mm']:.2f} mm"
        if response is None
        else f"electrostatic skin, {res['counts_per_ff']:.4g} counts per fF"
    )
    click.echo(
        f"{res['indenter']}: {fitted}, noise {res['noise_std_counts']:.2f} counts "
        f"-> {out_dir}/skin.toml",
        err=True,
    )
