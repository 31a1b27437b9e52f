"""`fruit live`: localize touches live from a MuCa board; JSON lines on stdout (mm)."""

from __future__ import annotations

import click

from fruitcli.cli.options import (
    FiniteFloat,
    Progress,
    baseline_frames_option,
    baud_option,
    divide_by_gain_option,
    format_option,
    fruit_errors,
    hovers_option,
    reduced_build_bar,
    skin_table_option,
    states_option,
    taxels_option,
    threshold_option,
)
from fruitcli.sensing.detection.drift import DEFAULT_TAU_S
from fruitcli.workflow.scene_outputs import scene_products


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
def live(
    scene_path,
    port,
    taxels_csv,
    states_npz,
    pressure_port,
    online,
    model_kind,
    n_frames,
    baud,
    fmt,
    baseline_frames,
    threshold,
    gains_csv,
    skin_toml,
    hovers,
    osc_target,
    tuio_3d,
    session_gate_mm,
    drift_tau_s,
    no_drift,
    reconnect,
    log_path,
    log_max_kb,
    log_backups,
    view_target,
    time_scale,
) -> None:
    """Stream touches of every frame from PORT as JSON lines on stdout.

    One line per frame with touches, and one with "touches": [] when they end:
    {"frame", "t_s", "touches": [{"touch", "i", "j", "x_mm", "y_mm", "z_mm", "peak",
    "height_mm", "height_err_mm", "strength", "size_mm", "kind"}]} (touch: the session
    id, kept by a finger across frames, from hover to touch; kind touch or hover). The
    baseline follows slow drift unless --no-drift.
    """
    import threading

    from fruitcli.errors import FrameError
    from fruitcli.scene import load_scene
    from fruitcli.sensing.detection.drift import DriftTracker
    from fruitcli.sensing.detection.frames_to_touches import Locator, Settings
    from fruitcli.sensing.detection.gain_division import detection_gain
    from fruitcli.sensing.detection.locate import load_states
    from fruitcli.sensing.live.idle_gc import FrameGC
    from fruitcli.sensing.live.loop import LiveLocator, pressure_thread
    from fruitcli.sensing.live.outputs import Outputs
    from fruitcli.sensing.live.serial_ports import FrameReader, PortClosed, PressureState, open_port
    from fruitcli.tables import read_taxels
    from fruitcli.workflow.online_model import (
        online_products,
        online_reduced,
        online_solver,
        reduced_source,
    )

    progress = Progress("[live] ")
    stop = threading.Event()
    with fruit_errors():
        scene = load_scene(scene_path)
        settings = Settings.from_scene(
            scene.detection,
            baseline_frames=baseline_frames,
            threshold_counts=threshold,
            hovers=hovers,
        )
        skin_table = scene.skin
        if skin_toml is not None:
            from fruitcli.sensing.detection.model_fit import check_skin_file
            from fruitcli.sensing.skin.heights import skin_with_gap_law

            skin_table = skin_with_gap_law(skin_toml)
            check_skin_file(skin_toml, settings.method)
        if n_frames is not None and n_frames <= settings.baseline_frames:
            raise FrameError(
                f"--frames {n_frames}: expected more than the "
                f"{settings.baseline_frames} baseline frames (--baseline-frames "
                "or the scene's [detection]); nothing could be located"
            )
        osc_address = None
        if osc_target is not None:
            from fruitcli.sensing.outputs.tuio import parse_host_port, resolve

            osc_address = resolve(*parse_host_port(osc_target, "--osc"), "--osc")
        taxels_csv = taxels_csv or scene.grid.taxels
        if online and model_kind == "reduced":  # the scene's reduced model
            taxels_csv, reduced = online_reduced(
                scene, scene_path, taxels_csv, pressure_port, progress, reduced_build_bar
            )
        elif online:  # the scene's mesh (tetra), not its states
            taxels_csv, mesh_npz = online_products(
                scene, scene_path, taxels_csv, pressure_port, progress
            )
        elif taxels_csv is None:
            taxels_csv, found_states = scene_products(scene)
            states_npz = states_npz or found_states
        if taxels_csv is None:
            raise FrameError(f"{scene_path}: no taxels: give --taxels or [grid].taxels")
        if pressure_port and not online and not states_npz:
            raise FrameError(
                f"--pressure-port {pressure_port}: nothing uses the pressures; "
                "it needs --states or --online, or the scene's states"
            )
        taxels = read_taxels(taxels_csv, FrameError)
        board = scene.board
        states = load_states(states_npz, len(taxels)) if states_npz else None
        gain = detection_gain(scene, taxels, gains_csv)
        from fruitcli.sensing.stages import skin_heights

        heights = skin_heights(skin_table, taxels, settings, gain is not None)
        pressure = solver = None
        if online:
            solver = (
                online_solver(scene, mesh_npz, taxels.xyz_mm, progress)
                if model_kind == "full"
                else reduced_source(reduced, taxels, taxels_csv)
            )
            loc = Locator(
                taxels,
                board,
                solver.taxels_mm,
                settings,
                where=str(taxels_csv),
                gain=gain,
                heights=heights,
            )
            pressure = PressureState(tuple(solver.model.chamber_names))
        elif states is None:
            loc = Locator(
                taxels,
                board,
                taxels.xyz_mm,
                settings,
                where=str(taxels_csv),
                gain=gain,
                heights=heights,
            )
        elif pressure_port:
            loc = Locator(
                taxels,
                board,
                states.taxels_mm,
                settings,
                states.pressure_kpa,
                where=str(taxels_csv),
                gain=gain,
                heights=heights,
            )
            pressure = PressureState(states.chamber_names)
        else:
            loc = Locator(
                taxels,
                board,
                states.taxels_mm[0],
                settings,
                where=str(taxels_csv),
                gain=gain,
                heights=heights,
            )
        drift = None if no_drift else DriftTracker(drift_tau_s, settings.threshold_counts)
        live_loc = LiveLocator(
            loc, pressure, solver, gate_mm=session_gate_mm, drift=drift, health=True
        )
        outputs = Outputs(live_loc, taxels, progress, time_scale, pressure)
        if osc_address is not None:
            from fruitcli.sensing.outputs.tuio import Normalizer, TuioSender

            outputs.tuio = TuioSender(
                osc_address, Normalizer.from_taxels(taxels.i, taxels.j, taxels.xyz_mm), tuio_3d
            )
            progress(f"TUIO/OSC to {osc_target} ({osc_address[0]})")
        if log_path is not None:
            from fruitcli.sensing.live.run_log import RunLog

            outputs.log = RunLog(log_path, log_max_kb * 1024, log_backups)
        if view_target is not None:
            outputs.start_view(view_target)
        if reconnect:
            from fruitcli.sensing.live.reconnect import wait_for_port

            try:
                ser = wait_for_port(
                    port, baud, on_wait=lambda why: progress(f"{why}; waiting for it (--reconnect)")
                )
            except KeyboardInterrupt:
                click.echo("Interrupted.", err=True)
                raise SystemExit(130) from None
        else:
            ser = open_port(port, baud)
        pser = p_thread = fem_thread = None
        if pressure is not None:
            pser = open_port(pressure_port, baud)
            p_thread = pressure_thread(pser, pressure, stop, pressure_port)
        if solver is not None:  # nothing to solve until a pressure line arrived
            fem_thread = solver.run(lambda: pressure.kpa if pressure.received else None, stop)
        frame_format = fmt or board.format
        reader = FrameReader(ser, board.rows, board.cols, name=port, fmt=frame_format)
        progress(f"collecting {settings.baseline_frames} baseline frames from {port}")
        seen = 0
        warned = False
        frame_gc = FrameGC().__enter__()  # garbage collection between frames, not in one
        try:
            while n_frames is None or seen < n_frames:
                try:
                    got = reader.poll()
                except PortClosed:
                    if not reconnect:
                        raise
                    outputs.skipped += reader.skipped
                    ser.close()
                    ser, reader = outputs.reconnect(port, baud, board, frame_format, wait_for_port)
                    continue
                if not seen and not warned and sum(reader.wrong_size.values()) >= 10:
                    warned = True  # the board's frames do not fit [board]: say it once
                    progress(
                        f"no frame yet, {reader.skipped} lines skipped: "
                        f"{reader.skip_reasons()} ([board] rows x cols)"
                    )
                for counts, t_s, _ in got:
                    outputs.frame(counts, reader.t0 + t_s)
                    seen += 1
                    if n_frames is not None and seen >= n_frames:
                        break
                frame_gc.after_frame()
        except PortClosed:
            why = reader.skip_reasons()
            raise FrameError(
                f"{port}: port closed after {seen} frames "
                f"({reader.skipped} lines skipped{': ' + why if why else ''})"
            ) from None
        except KeyboardInterrupt:
            click.echo("Interrupted.", err=True)
            raise SystemExit(130) from None
        finally:
            frame_gc.__exit__()
            stop.set()
            ser.close()
            outputs.close()
            if fem_thread is not None:
                fem_thread.join(0.5)  # an idle thread ends at once
            if fem_thread is not None and fem_thread.is_alive():
                progress("waiting for the online FEM to finish its state")
                fem_thread.join(FEM_JOIN_S)
                if fem_thread.is_alive():
                    progress(f"the online FEM is still solving after {FEM_JOIN_S:g} s; leaving it")
            if p_thread is not None:
                p_thread.join(1.0)
                pser.close()
            for line in _summary(seen, reader, pressure, solver) + outputs.summary():
                progress(line)


FEM_JOIN_S = 30.0
"""How long `fruit live` waits at exit for the online FEM's current state (a state takes
tens of ms; a hard one with load subdivisions a few seconds)."""


def _summary(seen, reader, pressure, solver) -> list[str]:
    """The closing lines of `fruit live`: frames, skipped lines, online FEM."""
    why = reader.skip_reasons()
    lines = [f"{seen} frames, {reader.skipped} lines skipped" + (f": {why}" if why else "")]
    if pressure is not None:
        lines.append(
            f"pressure lines: {pressure.received} taken, {pressure.skipped} skipped "
            f"(not 'P name=kPa ...' with known chambers {', '.join(pressure.chambers)} "
            "and finite values)"
        )
        if pressure.closed:
            lines.append(
                "the pressure port closed during the run: the taxels kept the last "
                "pressures received"
            )
    if solver is not None:
        lines.append(solver.summary())
    return lines
