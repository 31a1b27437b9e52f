"""`fruit make-tracks ARTIST --out DIR`: reduced body, carved yarn tracks, taxels."""

from __future__ import annotations

import click

from fruitcli.cli.options import FiniteFloat, Progress, fruit_errors, out_option
from fruitcli.geometry.mesh.units import UNIT_TO_MM
from fruitcli.scene import MAX_FACES


@click.command("make-tracks")
@click.argument("artist", type=click.Path(dir_okay=False))
@out_option(
    "Output folder (reduced.stl, tracked_top.stl, tracks.stl, taxels.csv, report.json, "
    "preview.png).",
    dest="out",
)
@click.option(
    "--unit",
    type=click.Choice(list(UNIT_TO_MM)),
    default=None,
    help="Unit of the mesh file (default: mm; read in mm, a mesh under 2 mm across "
    "is refused as being in m or cm).",
)
@click.option(
    "--fit-mm",
    type=FiniteFloat(),
    default=None,
    metavar="L",
    help="Scale the mesh uniformly (after --unit) so that its largest extent is L "
    "mm: the size the piece will be cast at.",
)
@click.option(
    "--cover-mm",
    type=FiniteFloat(),
    default=2.0,
    show_default=True,
    help="Inward offset left for the cover layer (mm).",
)
@click.option(
    "--faces",
    type=click.IntRange(4, MAX_FACES),
    default=5000,
    show_default=True,
    help="Target triangle count of the reduced surface.",
)
@click.option(
    "--spacing-x-mm",
    type=FiniteFloat(),
    default=16.0,
    show_default=True,
    help="Distance between the x = const cutting planes (mm).",
)
@click.option(
    "--spacing-y-mm",
    type=FiniteFloat(),
    default=12.0,
    show_default=True,
    help="Distance between the y = const cutting planes (mm).",
)
@click.option(
    "--origin-mm",
    type=(float, float),
    default=None,
    metavar="X Y",
    help="A point the grid planes pass through (mm; default: grid centred on the top surface).",
)
@click.option(
    "--track-radius-mm",
    type=FiniteFloat(),
    default=0.6,
    show_default=True,
    help="Radius of the yarn tubes carved into the surface (mm).",
)
@click.option(
    "--split-z-mm",
    type=FiniteFloat(),
    default=None,
    help="Height of the casting split plane (mm; default: the body's widest horizontal section).",
)
def make_tracks(
    artist,
    out,
    unit,
    fit_mm,
    cover_mm,
    faces,
    spacing_x_mm,
    spacing_y_mm,
    origin_mm,
    track_radius_mm,
    split_z_mm,
) -> None:
    """Reduce an artist mesh (STL/OBJ/PLY/OFF/glTF, mm), carve yarn tracks, export the taxels.

    Any surface with an inside is taken: holes are closed by the level set, overlapping
    parts become their union (generalized winding number); what was found is reported
    on stderr and in report.json.

    Paper Section III-D: inward offset by the cover thickness with far fewer triangles,
    sections x = x0 + k*16 mm and y = y0 + k*12 mm on the top side, tubes subtracted in one
    batch boolean, taxels at the crossings (i along x, j along y).
    """
    from fruitcli.geometry.tracks.make_tracks import make_tracks as run

    progress = Progress()
    with fruit_errors():
        report = run(
            artist,
            out,
            unit=unit,
            fit_mm=fit_mm,
            cover_mm=cover_mm,
            faces=faces,
            spacing_x_mm=spacing_x_mm,
            spacing_y_mm=spacing_y_mm,
            origin_mm=origin_mm,
            track_radius_mm=track_radius_mm,
            split_z_mm=split_z_mm,
            progress=progress,
        )
    progress(
        f"{report['taxels']} taxels, Hausdorff {report['offset_error']['hausdorff_mm']:.3f} "
        f"mm, reduced {report['triangles']['reduced']} triangles -> {out}"
    )
