"""`fruit skin`: the electrostatics of a scene's yarn crossing (mm, fF, counts)."""

from __future__ import annotations

from pathlib import Path

import click

from fruitcli.cli.options import Progress, fruit_errors, out_option


@click.command(name="skin")
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@out_option("Output folder: crossing.npz, summary.json.", path_type=Path)
def skin(scene, out_dir) -> None:
    """C0 of SCENE's Tx-Rx crossing, its change dC under the bench's indenters and a
    finger over gaps and offsets, and C_delta under stretch and bend.

    The cell comes from [grid] (pitch), [tracks] (cover, yarn radius) and [skin]
    (permittivity, yarn_radius_mm, insulation_mm, gaps_mm); gmsh is killed after
    [mesh] time_limit_s. Writes crossing.npz (the table) and summary.json (counts per
    fF fitted to the paper's bent pad, and per object the footprint sigma, gap decay and
    activation at contact).
    """
    from fruitcli.electrostatics.design import crossing_inputs, run_crossing, write_outputs
    from fruitcli.scene import load_scene

    with fruit_errors():
        inputs = crossing_inputs(load_scene(scene))
        table, summary = run_crossing(inputs, progress=Progress("skin "))
        write_outputs(out_dir, table, summary)
    click.echo(
        f"{out_dir / 'crossing.npz'}: C0 {summary['c0_ff']:.1f} fF, "
        f"{summary['counts_per_ff']:.3f} counts/fF"
    )
    for name, obj in summary["objects"].items():
        click.echo(
            f"  {name}: contact {obj['contact_counts']:.1f} counts, footprint sigma "
            f"{obj['footprint_sigma_mm']:.2f} mm, gap decay {obj['gap_decay_mm']:.2f} mm"
        )
