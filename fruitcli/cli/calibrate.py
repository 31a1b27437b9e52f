"""`fruit calibrate`: fit the skin's forward model to a bench recording (mm, counts)."""

from __future__ import annotations

import click

from fruitcli.cli.options import (
    Progress,
    fruit_errors,
    out_option,
    states_option,
    taxels_option,
)
from fruitcli.workflow.scene_outputs import scene_products


@click.command()
@click.argument("frames", type=click.Path(dir_okay=False))
@click.option(
    "--truth",
    "truth_csv",
    default=None,
    type=click.Path(dir_okay=False),
    help="truth.csv of the same bench run (sample,x_mm,y_mm,z_mm, model mm); without "
    "it, only the footprint's width, from the touches alone.",
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
@states_option("without --truth, the recording's taxels are at that state (its meta's)")
@out_option("Output folder: skin.toml ([skin] table), gains.csv, calibration.json.")
def calibrate(frames, truth_csv, scene_path, taxels_csv, indenter, states_npz, out_dir) -> None:
    """Fit footprint width, activation at contact, gap decay, per-taxel gains and noise to
    a bench recording (FRAMES: frames.npz of `fruit bench`, virtual or --printer).

    With the scene's [skin] model = "electrostatic": the crossing table's counts per fF
    (the table from the scene's skin stage), per-taxel gains and noise instead.

    Without --truth, any recording of touches: the footprint's width at which the model
    method explains its touches best, the rest of skin.toml the scene's [skin] (no gains;
    the Gaussian skin only)."""
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
        if truth_csv is None:
            from fruitcli.sensing.touch_width import run_touch_width

            res = run_touch_width(scene, frames, taxels, out_dir, indenter, states_npz, progress)
            click.echo(
                f"{res['indenter']}: footprint sigma {res['footprint_sigma_mm']:.2f} mm from "
                f"{res['touches']} touches ({res['width_scale']:.3f} times the scene's) "
                f"-> {out_dir}/skin.toml",
                err=True,
            )
            return
        if states_npz is not None:
            raise click.UsageError(
                "--states: only without --truth (a bench run's truth is at rest)"
            )
        response = crossing_response(scene, progress=progress)
        inputs = calibrate_inputs(scene)
        res = run_calibrate(
            inputs, frames, truth_csv, taxels, out_dir, indenter, progress, response
        )
    fitted = (
        f"footprint sigma {res['footprint_sigma_mm']:.2f} mm, contact "
        f"{res['contact_counts']:.1f} counts, gap decay {res['gap_decay_mm']:.2f} mm, a "
        f"crossing's height difference as distance {res['height_as_distance']:.2f} and as gap "
        f"{res['height_as_gap']:.2f}"
        if response is None
        else f"electrostatic skin, {res['counts_per_ff']:.4g} counts per fF"
    )
    click.echo(
        f"{res['indenter']}: {fitted}, noise {res['noise_std_counts']:.2f} counts "
        f"-> {out_dir}/skin.toml",
        err=True,
    )
