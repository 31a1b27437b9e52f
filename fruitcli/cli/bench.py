"""`fruit bench`: the virtual 3D-printer bench, frames with ground truth (mm, counts)."""

from __future__ import annotations

import click

from fruitcli.cli.options import Progress, fruit_errors, scene_products


def scene_surface(scene):
    """(path, unit) of the scene's body surface at rest in out/<scene name>, or (None, mm)."""
    from pathlib import Path

    from fruitcli.planner import Context
    from fruitcli.stages import solid_path

    path = solid_path(scene, Context(Path("out") / scene.name))
    unit = scene["geometry"]["unit"] if scene["geometry"]["solid"] is not None else "mm"
    return path, unit


@click.command()
@click.argument("scene_path", metavar="SCENE", type=click.Path(dir_okay=False))
@click.option("--taxels", "taxels_csv", type=click.Path(dir_okay=False), default=None,
              help="Taxel CSV (id,i,j,x_mm,y_mm,z_mm); default: the scene's own (its stages "
                   "run into out/<scene name> when needed).")
@click.option("--states", "states_npz", type=click.Path(dir_okay=False), default=None,
              help="states.npz from `fruit simulate`; without it the bench runs on the "
                   "taxels' own surface at rest.")
@click.option("--surface", "surface", type=click.Path(dir_okay=False), default=None,
              help="The body's closed surface at rest (mm), on which the truth lies; "
                   "default: the scene's own (reduced.stl or its solid).")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False),
              help="Output folder: <indenter>/frames.npz and <indenter>/truth.csv.")
def bench(scene_path, taxels_csv, states_npz, surface, out_dir):
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
        unit = "mm"
        if taxels is None:
            taxels, states_npz = scene_products(scene, progress=progress)
            if surface is None:
                surface, unit = scene_surface(scene)
        if taxels is None:
            raise FrameError(f"{scene_path}: no taxels: give --taxels or [grid].taxels")
        res = run_bench(scene, taxels, states_npz, out_dir, progress, surface, unit)
    click.echo(f"truth on {res['truth_surface']}", err=True)
    for name, r in res["indenters"].items():
        click.echo(f"{name}: {r['samples']} samples recorded ({r['dropped']} never reached "
                   "the threshold), "
                   f"{r['frames']} frames -> {out_dir}/{name}", err=True)
