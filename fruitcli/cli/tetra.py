"""`fruit tetra`: tetrahedralize a scene's body with its chambers (mm)."""

from __future__ import annotations

from pathlib import Path

import click

from fruitcli.cli.options import Progress, fruit_errors, out_option


@click.command(name="tetra")
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@out_option("Output folder: mesh.npz, mesh.msh, mesh.vtu, quality.json.", path_type=Path)
@click.option(
    "--solid",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Closed surface of the body (mm), e.g. reduced.stl from make-tracks; "
    "default: the scene's geometry.solid or pad_size_mm.",
)
def tetra(scene, out_dir, solid) -> None:
    """Linear tets of SCENE's body at [mesh] size_mm (mm), chambers as cavities.

    gmsh runs in a child process killed after [mesh] time_limit_s seconds; meshes whose
    worst SICN is below [mesh] min_quality are refused.
    """
    from fruitcli.fem.stage import run_tetra
    from fruitcli.scene import load_scene

    with fruit_errors():
        sc = load_scene(scene)
        report = run_tetra(sc, solid, out_dir, progress=Progress("tetra "))
    click.echo(
        f"{out_dir / 'mesh.npz'}: {report['n_tets']} tets, {report['n_nodes']} nodes, "
        f"SICN min {report['sicn_min']:.3f} mean {report['sicn_mean']:.3f}"
    )
