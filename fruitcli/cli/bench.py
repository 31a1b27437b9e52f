"""`fruit bench`: the virtual 3D-printer bench, frames with ground truth (mm, counts)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import click

from fruitcli.cli.options import (
    Progress,
    baud_option,
    format_option,
    fruit_errors,
    out_option,
    states_option,
    taxels_option,
)
from fruitcli.workflow.scene_outputs import scene_products

if TYPE_CHECKING:
    from pathlib import Path

    from fruitcli.printer.indentation import PrinterBenchInputs
    from fruitcli.scene import Scene


def scene_surface(scene: Scene) -> tuple[Path | None, str]:
    """(path, unit) of the scene's body surface at rest in out/<scene name>, or (None, mm)."""
    from pathlib import Path

    from fruitcli.workflow.planner import Context
    from fruitcli.workflow.stage_paths import solid_path

    path = solid_path(scene, Context(Path("out") / scene.name))
    unit = scene.geometry.unit if scene.geometry.solid is not None else "mm"
    return path, unit


@click.command()
@click.argument("scene_path", metavar="SCENE", type=click.Path(dir_okay=False))
@taxels_option()
@states_option("without it the bench runs on the taxels' own surface at rest.")
@click.option(
    "--surface",
    "surface",
    type=click.Path(dir_okay=False),
    default=None,
    help="The body's closed surface at rest (mm), on which the truth lies; "
    "default: the scene's own (reduced.stl or its solid).",
)
@out_option("Output folder: <indenter>/frames.npz and <indenter>/truth.csv.")
@click.option(
    "--skin",
    "skin_toml",
    type=click.Path(dir_okay=False),
    default=None,
    help="A [skin] table (e.g. `fruit calibrate`'s skin.toml) instead of the "
    "scene's: the virtual bench's skin.",
)
@click.option(
    "--printer",
    "printer_port",
    default=None,
    help="Real bench: the Marlin printer's serial port (with --board; the "
    "scene's [printer] says where the model sits and how to move).",
)
@click.option(
    "--board",
    "board_port",
    default=None,
    help="Real bench: the MuCa board's serial port (with --printer).",
)
@click.option(
    "--indenter",
    default=None,
    help="Real bench: the indenter on the printer (output folder name; default: "
    "the first of [bench].indenters).",
)
@format_option(default=None, what="Real bench: ")
@baud_option(name="--board-baud", what="Real bench: the board's line. ")
@click.option(
    "--overwrite", is_flag=True, help="Real bench: replace an existing <indenter>/frames.npz."
)
def bench(
    scene_path,
    taxels_csv,
    states_npz,
    surface,
    out_dir,
    skin_toml,
    printer_port,
    board_port,
    indenter,
    fmt,
    board_baud,
    overwrite,
) -> None:
    """Replay the paper's bench protocol on the model for SCENE's [bench] section, or run
    it on a real printer and board (--printer, --board).

    For each sample point (a quarter taxel off each grid point, or given points) the
    indenter descends in [bench].step_mm steps until some taxel's activation exceeds
    the threshold; that frame is recorded with the contact point as truth. On a real
    printer: safe height, M400 after every move, the next whole frame after it, retract;
    a bed limit, no touch, a printer error, a vanished port or Ctrl-C retracts, keeps
    every frame recorded and stops with one line naming the sample.
    """
    if printer_port or board_port:
        if skin_toml:
            raise click.UsageError(
                "--skin models the virtual bench's skin; the real bench "
                "(--printer, --board) measures the real one"
            )
        return real_bench(
            scene_path,
            taxels_csv,
            states_npz,
            out_dir,
            printer_port,
            board_port,
            indenter,
            fmt,
            board_baud,
            overwrite,
        )
    from fruitcli.errors import FrameError
    from fruitcli.scene import load_scene, load_skin_table
    from fruitcli.sensing.stages import run_bench

    progress = Progress("[bench] ")
    with fruit_errors():
        scene = load_scene(scene_path)
        if skin_toml:
            scene = scene.with_values({"skin": load_skin_table(skin_toml)})
        taxels = taxels_csv or scene.grid.taxels
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
        click.echo(
            f"{name}: {r['samples']} samples recorded ({r['dropped']} never reached "
            "the threshold), "
            f"{r['frames']} frames -> {out_dir}/{name}",
            err=True,
        )


def real_bench(
    scene_path: str | Path,
    taxels_csv: Path | None,
    states_npz: Path | None,
    out_dir: Path,
    printer_port: str | None,
    board_port: str | None,
    indenter: str | None,
    fmt: str,
    board_baud: int,
    overwrite: bool,
) -> None:
    """`fruit bench --printer --board`: the protocol on hardware (fruitcli.bench)."""
    from fruitcli.errors import SceneError
    from fruitcli.printer.indentation import BenchInterrupted, run_printer_bench
    from fruitcli.scene import load_scene

    progress = Progress("[bench] ")
    with fruit_errors():
        if not (printer_port and board_port):
            raise click.UsageError("the real bench needs both --printer and --board")
        scene = load_scene(scene_path)
        if not scene.has("printer"):
            raise SceneError(
                f"{scene_path}: no [printer] table (where the model sits on the "
                "bed, how to move): needed with --printer"
            )
        name = indenter or scene.bench.indenters[0]
        if not name or any(c in name for c in "/\\") or name in (".", ".."):
            raise click.BadParameter(f"{name!r}: expected a plain name", param_hint="--indenter")
        taxels = taxels_csv or scene.grid.taxels
        if taxels is None:
            taxels, found = scene_products(scene, progress=progress)
            states_npz = states_npz or found
        if taxels is None:
            raise SceneError(
                f"{scene_path}: no taxels: give --taxels or [grid].taxels (a CSV of "
                "id,i,j,x_mm,y_mm,z_mm)"
            )
        try:
            res = run_printer_bench(
                printer_bench_inputs(scene),
                taxels,
                states_npz,
                printer_port,
                board_port,
                out_dir,
                name,
                fmt or scene.board.format,
                board_baud,
                progress,
                overwrite,
            )
        except BenchInterrupted as exc:
            click.echo(f"Interrupted: {exc}", err=True)
            raise SystemExit(130) from None
    click.echo(
        f"{name}: {res['samples']} samples, {res['frames']} frames "
        f"({res['resends']} lines resent) -> {res['out']}",
        err=True,
    )


def printer_bench_inputs(scene: Scene) -> PrinterBenchInputs:
    """What the printer bench reads of `scene` (`indentation.PrinterBenchInputs`)."""
    from fruitcli.printer.indentation import PrinterBenchInputs
    from fruitcli.sensing.bench_stage import sample_spec

    return PrinterBenchInputs(
        scene_name=scene.name,
        file_name=scene.path.name,
        printer=scene.printer,
        board=scene.board,
        threshold_counts=scene.detection.threshold_counts,
        baseline_frames=max(scene.bench.baseline_frames, scene.detection.baseline_frames),
        state=scene.bench.state,
        samples=sample_spec(scene),
    )
