"""`fruit simulate`: quasi-static FEM of every actuation state (mm, kPa) on the
scene's [fem].element and [material].model."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import click

from fruitcli.cli.options import (
    Progress,
    fruit_errors,
    out_option,
    progressbar,
    reduced_build_bar,
    taxels_option,
)
from fruitcli.workflow.scene_outputs import shared_outputs

if TYPE_CHECKING:
    from fruitcli.scene import Scene


@click.command(name="simulate")
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@out_option("Output folder: mesh files and states.npz.", path_type=Path)
@click.option(
    "--solid",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Closed surface of the body (mm), e.g. reduced.stl. For an artist scene "
    "without it, make-tracks runs first (into OUT/make-tracks).",
)
@taxels_option(path_type=Path)
@click.option("--vtu", is_flag=True, help="Also write one VTU per state for ParaView.")
@click.option(
    "--pressures",
    "pressures_csv",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="CSV of pressure vectors instead of [actuation]: one row per "
    "state, one column <chamber>_kpa per chamber (kPa), # comment lines allowed.",
)
@click.option(
    "--model",
    "model_kind",
    type=click.Choice(["full", "reduced"]),
    default="full",
    show_default=True,
    help="full: the FEM solved per state; reduced: the scene's "
    "reduced model (built into OUT/reduce on first use, pressures within its range).",
)
def simulate(scene, out_dir, solid, taxels_csv, vtu, pressures_csv, model_kind) -> None:
    """Tetrahedralize SCENE's body, then solve each state of [actuation].

    Pressures in kPa (or volume growth in mm^3) per chamber, jig springs in N/mm,
    gravity from [material] density_kg_m3 when the scene has [gravity]. Writes
    OUT/states.npz: rest_nodes, tets, displacement_mm (S,N,3), pressure_kpa (S,K),
    chamber_volume_mm3 (S,K), taxels_mm (S,T,3), iterations, residual, solve_ms, model;
    and OUT/yarns.csv (each track's rest length and largest stretch) when the scene has
    tracks (make-tracks' tracks.csv or [tracks] file). The pressures are checked against
    the chambers' limits first; the check's samples and the first state are kept in
    OUT/pressure-check.npz, and a later run on the same body reuses those still in
    equilibrium.

    With --pressures P.csv the states are the rows of P.csv (one column <chamber>_kpa per
    chamber). --model reduced evaluates the scene's reduced model instead of solving
    (built into OUT/reduce on first use; rows outside its range are refused; solve_ms
    is then the time of the evaluation).
    """
    from fruitcli.errors import SceneError
    from fruitcli.fem.stage import run_simulate, run_tetra
    from fruitcli.scene import load_scene, n_states

    log = Progress("simulate ")
    with fruit_errors():
        sc = load_scene(scene)
        names = [c.name for c in sc.chambers]
        table = rows = None
        if pressures_csv is not None:
            from fruitcli.fem.pressure_table import read_pressures

            if not names:
                raise SceneError(f"{scene}: --pressures: the scene has no [[geometry.chamber]]")
            table, rows = read_pressures(pressures_csv, names)
        if model_kind == "reduced":
            from fruitcli.workflow.reduced_model import simulate_reduced

            info = simulate_reduced(
                sc,
                out_dir,
                taxels_csv,
                table,
                rows,
                pressures_csv,
                log,
                vtu=vtu,
                bar=reduced_build_bar,
            )
            click.echo(
                f"{out_dir / 'states.npz'}: {info['states']} state(s) from the reduced "
                f"model, {info['us_per_state']:.1f} us per state; {info['describe']}"
            )
            return
        solid, xyz, taxel_csv, tracks_csv = _body_and_taxels(
            sc, scene, solid, taxels_csv, out_dir, log
        )
        run_tetra(sc, solid, out_dir, progress=log, taxels_xyz=xyz)
        with progressbar(
            length=n_states(sc) if table is None else len(table), label="states"
        ) as bar:

            def progress(msg: str) -> None:
                if msg.startswith("state "):
                    bar.update(1)
                else:
                    log(msg)

            info = run_simulate(
                sc,
                out_dir / "mesh.npz",
                xyz,
                out_dir,
                progress=progress,
                vtu=vtu,
                tracks_csv=tracks_csv,
                pressures=None if table is None else dict(zip(names, table.T, strict=True)),
                taxels_source=None if taxel_csv is None else str(taxel_csv),
            )
    click.echo(
        f"{out_dir / 'states.npz'}: {info['states']} state(s), Newton iterations "
        f"{info['iterations']}, solve ms {[round(t) for t in info['solve_ms']]}"
    )
    if "yarns" in info:
        _say_yarns(out_dir / "yarns.csv", info["yarns"])


def _body_and_taxels(
    sc: Scene,
    scene: str | Path,
    solid: Path | None,
    taxels_csv: Path | None,
    out_dir: Path,
    log: Callable[[str], None],
) -> tuple:
    """(the solid to mesh, the taxels (T, 3) mm or None, their CSV, the tracks' CSV): the
    given ones, checked before any stage runs, else an artist's from make-tracks (run
    into out_dir)."""
    from fruitcli.errors import SceneError
    from fruitcli.tables import read_taxels

    geo = sc.geometry
    taxel_csv = taxels_csv or sc.grid.taxels
    # given taxels are checked before any stage runs
    xyz = read_taxels(taxel_csv).xyz_mm if taxel_csv is not None else None
    tracks_csv = sc.tracks.file
    if tracks_csv is not None:
        from fruitcli.fem.yarn import read_tracks

        read_tracks(tracks_csv)
    if solid is None and geo.artist is not None:
        from fruitcli.workflow import planner

        planner.run(sc, out_dir, until="make-tracks", progress=log, shared=shared_outputs(out_dir))
        solid = out_dir / "make-tracks" / "reduced.stl"
        tracks_csv = tracks_csv or out_dir / "make-tracks" / "tracks.csv"
        if xyz is None:
            taxel_csv = out_dir / "make-tracks" / "taxels.csv"
            xyz = read_taxels(taxel_csv).xyz_mm
    elif solid is None and geo.solid is None and geo.pad_size_mm is None:
        raise SceneError(f"{scene}: [geometry]: no artist, solid or pad_size_mm to mesh")
    return solid, xyz, taxel_csv, tracks_csv


def _say_yarns(path: str | Path, y: dict) -> None:
    """The line on yarns.csv: the tracks and their largest stretch."""
    click.echo(
        f"{path}: {y['tracks']} track(s), largest stretch "
        f"{y['max_stretch_pct']:.2f} % over a track, {y['max_local_stretch_pct']:.2f}"
        f" % over {y['zigzag_pitch_mm']:g} mm (track {y['worst_track']}, state "
        f"{y['state_of_max']}); {len(y['warnings'])} over [tracks] yarn_max_stretch "
        f"{100 * y['yarn_max_stretch']:g} %"
    )
