"""`fruit limits`: each chamber's limit pressure (and collapse under suction), its
pressure-volume curve followed by volume control on the scene's mesh (mm, kPa)."""

from __future__ import annotations

from pathlib import Path

import click

from fruitcli.cli.options import Progress, fruit_errors, jobs_option, out_option
from fruitcli.workflow.scene_outputs import shared_outputs


@click.command(name="limits")
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@out_option("Output folder: mesh files, limits.json, pv.csv, pv.png.", path_type=Path)
@click.option(
    "--solid",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Closed surface of the body (mm), e.g. reduced.stl. For an artist scene "
    "without it, make-tracks runs first (into OUT/make-tracks).",
)
@jobs_option("Worker processes following the curves, one curve each at a time")
def limits(scene, out_dir, solid, jobs) -> None:
    """Follow each chamber of SCENE past its limit pressure by volume control.

    One chamber at a time, the others at rest: inflation until the pressure has passed
    its maximum (the limit pressure: no equilibrium above it under pressure control),
    suction until the cavity's walls would meet (the collapse pressure); with several
    chambers, also all together along the scene's own pressure ratios. Writes
    OUT/limits.json (chambers.<name>.limit_pressure_kpa, limit_volume_growth_mm3,
    collapse_pressure_kpa; null when not reached), OUT/pv.csv (chamber,
    volume_growth_mm3, pressure_kpa) and OUT/pv.png.
    """
    from fruitcli.errors import SceneError
    from fruitcli.fem.curve_peak import MAX_STRETCH
    from fruitcli.fem.limits_stage import run_limits
    from fruitcli.fem.stage import run_tetra
    from fruitcli.scene import load_scene
    from fruitcli.studies.parallel import CurveProcesses

    log = Progress("limits ")
    with fruit_errors():
        sc = load_scene(scene)
        if not sc.chambers:
            raise SceneError(f"{scene}: [[geometry.chamber]]: the scene has no chamber")
        geo = sc.geometry
        if solid is None and geo.artist is not None:
            from fruitcli.workflow import planner

            planner.run(
                sc, out_dir, until="make-tracks", progress=log, shared=shared_outputs(out_dir)
            )
            solid = out_dir / "make-tracks" / "reduced.stl"
        elif solid is None and geo.solid is None and geo.pad_size_mm is None:
            raise SceneError(f"{scene}: [geometry]: no artist, solid or pad_size_mm to mesh")
        run_tetra(sc, solid, out_dir, progress=log)
        pool = CurveProcesses(jobs)
        info = run_limits(sc, out_dir / "mesh.npz", out_dir, progress=log, pool=pool)
    for name, ch in info["chambers"].items():
        lim, col = ch["limit_pressure_kpa"], ch["collapse_pressure_kpa"]
        click.echo(
            f"chamber {name}: limit pressure "
            + (
                f"none up to {MAX_STRETCH**3:g} V0"
                if lim is None
                else f"{lim:.4g} kPa at {ch['limit_volume_growth_mm3']:.4g} mm^3 growth"
            )
            + ", collapse "
            + ("none" if col is None else f"{col:.4g} kPa")
        )
    together = info.get("together")
    if together:
        lim = together["limit_pressure_kpa"]
        click.echo(
            "chambers together (pressure ratios "
            + ", ".join(f"{c} {r:.3g}" for c, r in together["ratios"].items())
            + "): limit "
            + (
                f"none up to {MAX_STRETCH**3:g} V0"
                if lim is None
                else f"{lim:.4g} kPa in the chamber of ratio 1"
            )
        )
    click.echo(
        f"{out_dir / 'limits.json'}: {len(info['chambers'])} chamber(s), "
        f"{info['element']}, {info['seconds']:.1f} s"
    )
