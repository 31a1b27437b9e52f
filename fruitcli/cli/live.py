"""`fruit live`: localize touches live from a MuCa board; JSON lines on stdout (mm)."""

from __future__ import annotations

from typing import Any

import click

from fruitcli.cli import live_run as run
from fruitcli.cli.options import (
    FiniteFloat,
    Progress,
    baseline_frames_option,
    baud_option,
    divide_by_gain_option,
    format_option,
    fruit_errors,
    hovers_option,
    skin_table_option,
    states_option,
    taxels_option,
    threshold_option,
)
from fruitcli.errors import FrameError
from fruitcli.sensing.detection.drift import DEFAULT_TAU_S


@click.command()
@click.argument("scene_path", metavar="SCENE", type=click.Path(dir_okay=False))
@click.option("--port", required=True, help="Serial port of the board.")
@taxels_option()
@states_option("taxels follow the FEM states (state 0 without pressures).")
@click.option(
    "--pressure-port",
    default=None,
    help="Serial source of chamber pressures: lines 'P c1=2.5 c2=0.0' in kPa.",
)
@click.option(
    "--online",
    is_flag=True,
    help="Solve the FEM at every new measured pressure (in a background thread; "
    "needs --pressure-port and the scene's mesh) instead of interpolating "
    "the precomputed states.",
)
@click.option(
    "--model",
    "model_kind",
    type=click.Choice(["reduced", "full"]),
    default="reduced",
    show_default=True,
    help="With --online: reduced (the scene's reduced model, built into "
    "out/<scene name>/reduce on first use) or full (the FEM solved per "
    "pressure vector).",
)
@click.option(
    "--frames",
    "n_frames",
    type=click.IntRange(min=1),
    default=None,
    help="Stop after this many frames (baseline frames included).",
)
@baud_option()
@format_option(default=None)
@baseline_frames_option
@threshold_option
@divide_by_gain_option
@skin_table_option
@hovers_option
@click.option(
    "--osc",
    "osc_target",
    default=None,
    metavar="HOST:PORT",
    help="Send touches over OSC/UDP: TUIO 1.1 /tuio/2Dcur, /tuio/3Dcur and "
    "/tuio/_sp (peak), and plain /fruit/frame, /fruit/down, /fruit/touch, "
    "/fruit/up (README: 'Touches out').",
)
@click.option(
    "--tuio-3d",
    "tuio_3d",
    type=click.Choice(["3Dcur", "25Dcur"]),
    default="3Dcur",
    show_default=True,
    help="TUIO profile of the 3D position on the body.",
)
@click.option(
    "--session-gate-mm",
    type=FiniteFloat(min=0),
    default=20.0,
    show_default=True,
    help="A touch keeps its session id when it moved at most this far since the "
    "previous frame, mm (0: every frame's touches are new).",
)
@click.option(
    "--drift-tau-s",
    type=FiniteFloat(min=0, min_open=True),
    default=DEFAULT_TAU_S,
    show_default=True,
    help="Time constant of the baseline drift tracker, s (adapts only while no "
    "taxel is above half the threshold).",
)
@click.option(
    "--no-drift", is_flag=True, help="Keep the baseline fixed (as the paper's bench replays do)."
)
@click.option(
    "--reconnect",
    is_flag=True,
    help="When the port vanishes (cable pulled), wait for it, reopen it, take a "
    "new baseline and go on; also wait for it at start.",
)
@click.option(
    "--log",
    "log_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Append touches and a status line per minute to this rotating log file.",
)
@click.option(
    "--log-max-kb",
    type=click.IntRange(min=1),
    default=1024,
    show_default=True,
    help="Size of the log file before it rotates, kB.",
)
@click.option(
    "--log-backups",
    type=click.IntRange(min=1),
    default=5,
    show_default=True,
    help="Rotated log files kept (FILE.1 ...).",
)
@click.option(
    "--view",
    "view_target",
    default=None,
    metavar="[HOST:]PORT",
    help="Serve the live view (heat map, touches, pressures, frames/s, baseline) "
    "at http://HOST:PORT/ (HOST default 127.0.0.1: this machine only).",
)
@click.option(
    "--time-scale",
    type=FiniteFloat(min=0, min_open=True),
    default=1.0,
    help="Host time runs this many times faster, for compressed-time tests "
    "against an emulated board played as fast (tests/test_live_soak.py); "
    "scales t_s, the drift tracker and the status lines.",
)
def live(scene_path: str, **given: Any) -> None:
    """Stream touches of every frame from PORT as JSON lines on stdout.

    One line per frame with touches, and one with "touches": [] when they end:
    {"frame", "t_s", "touches": [{"touch", "i", "j", "x_mm", "y_mm", "z_mm", "peak",
    "height_mm", "height_err_mm", "strength", "size_mm", "kind"}]} (touch: the session
    id, kept by a finger across frames, from hover to touch; kind touch or hover). The
    baseline follows slow drift unless --no-drift.
    """
    import threading

    from fruitcli.scene import load_scene
    from fruitcli.sensing.detection.drift import DriftTracker
    from fruitcli.sensing.detection.settings import Settings
    from fruitcli.sensing.live.loop import LiveLocator, pressure_thread
    from fruitcli.sensing.live.serial_ports import FrameReader, PortClosed, open_port

    o = run.LiveOptions(**given)
    progress = Progress("[live] ")
    stop = threading.Event()
    with fruit_errors():
        scene = load_scene(scene_path)
        settings = Settings.from_scene(
            scene.detection,
            baseline_frames=o.baseline_frames,
            threshold_counts=o.threshold,
            hovers=o.hovers,
        )
        if o.n_frames is not None and o.n_frames <= settings.baseline_frames:
            raise FrameError(
                f"--frames {o.n_frames}: expected more than the "
                f"{settings.baseline_frames} baseline frames (--baseline-frames "
                "or the scene's [detection]); nothing could be located"
            )
        osc_address = None
        if o.osc_target is not None:
            from fruitcli.sensing.outputs.tuio import parse_host_port, resolve

            osc_address = resolve(*parse_host_port(o.osc_target, "--osc"), "--osc")
        loc, pressure, solver = run.locator(scene, scene_path, settings, o, progress)
        drift = None if o.no_drift else DriftTracker(o.drift_tau_s, settings.threshold_counts)
        live_loc = LiveLocator(
            loc, pressure, solver, gate_mm=o.session_gate_mm, drift=drift, health=True
        )
        out = run.outputs(live_loc, loc.taxels, o, osc_address, progress, pressure)
        ser = run.open_board(o, progress)
        pser = p_thread = fem_thread = None
        if pressure is not None and o.pressure_port:  # a pressure state needs its port
            pser = open_port(o.pressure_port, o.baud)
            p_thread = pressure_thread(pser, pressure, stop, o.pressure_port)
        if solver is not None:  # nothing to solve until a pressure line arrived
            fem_thread = solver.run(lambda: pressure.kpa if pressure.received else None, stop)
        board = scene.board
        frame_format = o.fmt or board.format
        reader = FrameReader(ser, board.rows, board.cols, name=o.port, fmt=frame_format)
        progress(f"collecting {settings.baseline_frames} baseline frames from {o.port}")
        state = run.Run(ser, reader)
        try:
            run.run_frames(state, out, o, board, frame_format, progress)
        except PortClosed:
            why = state.reader.skip_reasons()
            raise FrameError(
                f"{o.port}: port closed after {state.seen} frames "
                f"({state.reader.skipped} lines skipped{': ' + why if why else ''})"
            ) from None
        except KeyboardInterrupt:
            click.echo("Interrupted.", err=True)
            raise SystemExit(130) from None
        finally:
            stop.set()
            run.shut_down(state, out, (fem_thread, p_thread), pser, pressure, solver, progress)
