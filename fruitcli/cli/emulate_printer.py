"""`fruit emulate-printer`: a Marlin-like printer and a MuCa-like board on two
pseudo-terminals, the board's frames made by the skin's forward model at the tip."""

from __future__ import annotations

import sys
from collections.abc import Iterable

import click

from fruitcli.cli.options import (
    FiniteFloat,
    baud_option,
    format_option,
    fruit_errors,
    taxels_option,
)
from fruitcli.workflow.scene_outputs import scene_products


def parse_faults(specs: Iterable[str]) -> dict:
    """``resend:5`` ``no-ok:12`` ``halt:20`` -> {"resend": [5], ...}."""
    from fruitcli.printer.emulator import FAULTS

    out: dict[str, list[int]] = {}
    for spec in specs:
        kind, _, n = spec.partition(":")
        if kind not in FAULTS or not n.isdigit() or int(n) < 1:
            raise click.BadParameter(
                f"{spec!r}: expected KIND:N with KIND one of "
                f"{', '.join(FAULTS)} and N >= 1 (the N-th command "
                "line received)",
                param_hint="--fault",
            )
        out.setdefault(kind, []).append(int(n))
    return out


@click.command("emulate-printer")
@click.option(
    "--board-from",
    "scene_path",
    required=True,
    type=click.Path(dir_okay=False),
    help="Scene whose [printer] placement, [board] and taxels make the board's "
    "frames (its stages run into out/<scene name> when needed).",
)
@taxels_option()
@click.option(
    "--indenter",
    default="small",
    show_default=True,
    type=click.Choice(["small", "medium"]),
    help="The indenter the skin feels.",
)
@format_option(default="binary", auto=False)
@baud_option(pace=True, what="The board's bytes. ")
@click.option(
    "--time-scale",
    type=FiniteFloat(min=0),
    default=1.0,
    show_default=True,
    help="Moves take distance / feed rate times this (0: instantly).",
)
@click.option(
    "--fault",
    "faults",
    multiple=True,
    help="Inject a fault at the N-th command line: resend:N (checksum mismatch, "
    "once), no-ok:N (never answered), halt:N (Error:Printer halted).",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Skin and noise seed.")
@click.option(
    "--skin",
    "skin_toml",
    type=click.Path(dir_okay=False),
    default=None,
    help="A [skin] table (e.g. `fruit calibrate`'s skin.toml) instead of the scene's.",
)
def emulate_printer(
    scene_path, taxels_csv, indenter, fmt, baud, time_scale, faults, seed, skin_toml
) -> None:
    """Print the printer's and the board's pty paths, then answer on both until Ctrl-C
    (or until 5 s after the bench has closed the board's port).

    The printer answers the Marlin host protocol; the board sends frames of the skin
    under the printer's tip, so `fruit bench SCENE --printer P --board B` runs whole.
    """
    import threading

    from fruitcli.errors import FrameError, SceneError
    from fruitcli.printer.emulator import PrinterEmulator
    from fruitcli.printer.placement import Placement
    from fruitcli.printer.skin_board import SkinBoard
    from fruitcli.scene import load_scene, load_skin_table
    from fruitcli.sensing.live.board_emulator import BoardEmulator, pacing_line
    from fruitcli.sensing.skin import forward
    from fruitcli.tables import read_taxels
    from fruitcli.workflow.scene_outputs import crossing_response

    fault_table = parse_faults(faults)
    with fruit_errors():
        scene = load_scene(scene_path)
        if not scene.has("printer"):
            raise SceneError(f"{scene_path}: no [printer] table (where the model sits on the bed)")
        pr = scene.printer
        taxels_csv = taxels_csv or scene.grid.taxels or scene_products(scene)[0]
        taxels = read_taxels(taxels_csv, FrameError)
        bed = pr.bed_mm
        printer = PrinterEmulator(bed, (bed[0], bed[1], bed[5]), time_scale, fault_table)
        if skin_toml:
            scene = scene.with_values({"skin": load_skin_table(skin_toml)})
        params = forward.SkinParams.from_table(scene.skin)
        response = crossing_response(scene)
        skin = SkinBoard(
            taxels,
            scene.board,
            Placement.from_printer(pr),
            printer.tip_mm,
            indenter,
            seed,
            params,
            response,
        )
        board = BoardEmulator(skin.frame, fps=0, wait_for_reader=True, fmt=fmt, baud=baud)
        click.echo(f"printer: {printer.path}")
        click.echo(f"board: {board.path}")
        sys.stdout.flush()
        click.echo(
            f"board: {fmt} frames of the skin under the {indenter} tip, pacing: "
            f"{pacing_line(fmt, baud, *skin.shape)}",
            err=True,
        )
        threads = [printer.start(), threading.Thread(target=board.play, daemon=True)]
        threads[1].start()
        try:
            while all(th.is_alive() for th in threads):
                threads[0].join(0.2)
        except KeyboardInterrupt:
            pass
        finally:
            printer.stop.set()
            board.stop.set()
            for th in threads:
                th.join(2.0)
    click.echo(f"printer: {printer.received} command lines; board: {board.sent} frames", err=True)
