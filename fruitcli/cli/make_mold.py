"""`fruit make-mold SCENE --out DIR`: printable molds for the scene's cast pieces."""

from __future__ import annotations

from pathlib import Path

import click

from fruitcli.cli.options import Progress, fruit_errors, out_option
from fruitcli.workflow.scene_outputs import shared_outputs


def _opt(name: str, kind: click.ParamType | type, help_: str):
    return click.option(f"--{name.replace('_', '-')}", name, type=kind, default=None, help=help_)


@click.command("make-mold")
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@out_option("Output folder: one STL per mold part, mold.json, preview.png.", path_type=Path)
@click.option(
    "--tracks",
    "tracks_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="A make-tracks output folder; default: make-tracks runs first (into OUT/make-tracks).",
)
@_opt("wall_mm", float, "Mold wall thickness (mm; default 4, at least 1).")
@_opt(
    "clearance_mm",
    float,
    "Gap between keys and sockets, pins and holes (mm; default 0.3, at most the wall).",
)
@_opt("key_radius_mm", float, "Radius of the hemispherical registration keys (mm; default 3).")
@_opt("pour_diameter_mm", float, "Pour hole diameter (mm; default 8).")
@_opt("vent_diameter_mm", float, "Vent diameter (mm; default 2).")
@_opt("pin_diameter_mm", float, "Diameter of the pins holding the chamber cores (mm; default 3).")
@_opt("vents", int, "Vents at the cavity's highest points besides the pour hole (default 4).")
def make_mold(scene, out_dir, tracks_dir, **given) -> None:
    """Molds to cast SCENE's pieces in silicone: the tracked top (its yarn grooves are
    ridges on the shell's inner face) and the lower half, each a box split at the casting
    split plane into shell and plate, with registration keys, a pour hole and vents at the
    highest points, and a printable core on a locating pin for each chamber. Options
    default to the scene's [mold] section, then to the values shown."""
    from fruitcli.errors import SceneError
    from fruitcli.fabrication.mold import MoldOptions
    from fruitcli.fabrication.stage import CLI_NAMES, SCENE_NAMES, run_make_mold, scene_chambers
    from fruitcli.scene import load_scene

    log = Progress("make-mold ")
    with fruit_errors():
        sc = load_scene(scene)
        values = {
            k: (given[k] if given[k] is not None else getattr(sc.mold, k))
            for k in MoldOptions.__dataclass_fields__
        }
        names = {k: CLI_NAMES[k] if given[k] is not None else SCENE_NAMES[k] for k in values}
        opts = MoldOptions(**values)
        opts.check(names)
        if tracks_dir is None:
            if sc.geometry.artist is None:
                raise SceneError(
                    f"{scene}: [geometry]: make-mold needs an artist mesh (its "
                    "tracked top and reduced body), or --tracks"
                )
            from fruitcli.workflow import planner

            planner.run(
                sc, out_dir, until="make-tracks", progress=log, shared=shared_outputs(out_dir)
            )
            tracks_dir = out_dir / "make-tracks"
        report = run_make_mold(
            tracks_dir,
            out_dir,
            scene_chambers(sc),
            sc.material.density_kg_m3,
            opts,
            names,
            progress=log,
        )
    for m in report["molds"]:
        click.echo(
            f"{m['piece']}: {', '.join(m['parts'])}; {m['silicone_ml']} ml "
            f"({m['silicone_g']} g) of silicone; cavity / piece "
            f"{m['cavity_vs_piece']:.4f}"
        )
