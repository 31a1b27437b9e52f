"""`fruit make-artist --out FILE`: write the default artist mesh (the organic 'Fruit')."""

from __future__ import annotations

import click

from fruitcli.cli.options import Progress, fruit_errors, out_option


@click.command("make-artist")
@out_option("Output mesh file: .stl, .obj or .ply (mm).", file=True, dest="out")
@click.option("--overwrite", is_flag=True, help="Replace an existing --out file.")
def make_artist(out, overwrite) -> None:
    """Write the default artist mesh, a procedural 'Fruit' about 150 mm across (mm units,
    >= 100,000 triangles, closed), its top under the paper's 29 rest sample positions."""
    from pathlib import Path

    from fruitcli.errors import GeometryError
    from fruitcli.geometry.artist import write_artist

    progress = Progress()
    with fruit_errors():
        if Path(out).exists() and not overwrite:
            raise GeometryError(f"--out {out}: exists; give --overwrite to replace it")
        info = write_artist(out)
    progress(f"wrote {info['path']}: {info['triangles']} triangles, {info['volume_mm3']:.0f} mm^3")
