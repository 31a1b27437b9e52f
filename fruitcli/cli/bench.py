"""`fruit bench`: the virtual 3D-printer bench, frames with ground truth (mm, counts)."""

from __future__ import annotations

import click

from fruitcli.cli.options import Progress, fruit_errors, scene_products


@click.command()
@click.argument("scene_path", metavar="SCENE", type=click.Path(dir_okay=False))
@click.option("--taxels", "taxels_csv", type=click.Path(dir_okay=False), default=None,
              help="Taxel CSV (id,i,j,x_mm,y_mm,z_mm); default: the scene's own (its stages "
                   "run into out/<scene name> when needed).")
@click.option("--states", "states_npz", type=click.Path(dir_okay=False), default=None,
              help="states.npz from `fruit simulate`; without it the bench runs on the "
                   "taxels' own surface at rest.")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False),
              help="Output folder: <indenter>/frames.npz and <indenter>/truth.csv.")
def bench(scene_path, taxels_csv, states_npz, out_dir):
    """Replay the paper's bench protocol on the model for SCENE's [bench] section.

    For each sample point (a quarter taxel off each grid point, or given points) the
    indenter descends in [bench].step_mm steps until some taxel's activation exceeds
    the threshold; that frame is recorded with the contact point as truth.
    """
    from fruitcli.errors import FrameError
    from fruitcli.scene import load_scene
    from fruitcli.sensing.stage import run_bench

    progress = Progress("[bench] ")
    with fruit_errors():
        scene = load_scene(scene_path)
        taxels = taxels_csv or scene["grid"]["taxels"]
        if taxels is None:
            taxels, states_npz = scene_products(scene, progress=progress)
        if taxels is None:
            raise FrameError(f"{scene_path}: no taxels: give --taxels or [grid].taxels")
        res = run_bench(scene, taxels, states_npz, out_dir, progress)
    for name, r in res["indenters"].items():
        click.echo(f"{name}: {r['samples']} samples recorded ({r['dropped']} never reached "
                   "the threshold), "
                   f"{r['frames']} frames -> {out_dir}/{name}", err=True)
