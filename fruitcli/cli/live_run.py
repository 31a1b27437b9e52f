"""`fruit live`'s steps below its options: the taxels and positions the scene and
options name (`locator`), the outputs (`outputs`), the board's port (`open_board`), the
frame loop (`run_frames`) and the shutdown (`shut_down`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import click

from fruitcli.cli.options import Progress, reduced_build_bar
from fruitcli.errors import FrameError
from fruitcli.workflow.scene_outputs import scene_products

if TYPE_CHECKING:
    from serial import SerialBase

    from fruitcli.fem.online import OnlineSolver, ReducedOnline
    from fruitcli.scene import BoardSection, Scene
    from fruitcli.sensing.detection.settings import Settings
    from fruitcli.sensing.live.loop import LiveLocator
    from fruitcli.sensing.live.outputs import Outputs
    from fruitcli.sensing.live.serial_ports import FrameReader, PressureState
    from fruitcli.tables import Taxels

FEM_JOIN_S = 30.0
"""How long `fruit live` waits at exit for the online FEM's current state (a state takes
tens of ms; a hard one with load subdivisions a few seconds)."""


@dataclass(frozen=True)
class LiveOptions:
    """`fruit live`'s options, as click passes them (see the command's --help)."""

    port: str
    taxels_csv: str | None
    states_npz: str | None
    pressure_port: str | None
    online: bool
    model_kind: str
    n_frames: int | None
    baud: int
    fmt: str | None
    baseline_frames: int | None
    threshold: float | None
    gains_csv: str | None
    skin_toml: str | None
    hovers: bool | None
    osc_target: str | None
    tuio_3d: str
    session_gate_mm: float
    drift_tau_s: float
    no_drift: bool
    reconnect: bool
    log_path: str | None
    log_max_kb: int
    log_backups: int
    view_target: str | None
    time_scale: float


def _taxel_products(scene: Scene, scene_path: str, o: LiveOptions, progress: Progress) -> tuple:
    """(taxels.csv, states.npz or None, the reduced model or None, the mesh.npz or None):
    from the options, else the online model's products, else the scene's outputs."""
    from fruitcli.workflow.online_model import online_products, online_reduced

    taxels_csv = o.taxels_csv or scene.grid.taxels
    states_npz: str | Path | None = o.states_npz
    reduced = mesh_npz = None
    if o.online and o.model_kind == "reduced":  # the scene's reduced model
        taxels_csv, reduced = online_reduced(
            scene, scene_path, taxels_csv, o.pressure_port, progress, reduced_build_bar
        )
    elif o.online:  # the scene's mesh (tetra), not its states
        taxels_csv, mesh_npz = online_products(
            scene, scene_path, taxels_csv, o.pressure_port, progress
        )
    elif taxels_csv is None:
        taxels_csv, found_states = scene_products(scene)
        states_npz = states_npz or found_states
    if taxels_csv is None:
        raise FrameError(f"{scene_path}: no taxels: give --taxels or [grid].taxels")
    if o.pressure_port and not o.online and not states_npz:
        raise FrameError(
            f"--pressure-port {o.pressure_port}: nothing uses the pressures; "
            "it needs --states or --online, or the scene's states"
        )
    return taxels_csv, states_npz, reduced, mesh_npz


def locator(
    scene: Scene, scene_path: str, settings: Settings, o: LiveOptions, progress: Progress
) -> tuple:
    """(the `Locator`, the `PressureState` or None, the online solver or None) of the
    scene's taxels: at rest, on the FEM states (following the pressure port when given),
    or on the online model."""
    from fruitcli.sensing.detection.frames_to_touches import Locator
    from fruitcli.sensing.detection.gain_division import detection_gain
    from fruitcli.sensing.detection.locate import load_states
    from fruitcli.sensing.inputs_stage import gain_inputs
    from fruitcli.sensing.live.serial_ports import PressureState
    from fruitcli.sensing.locator_setup import skin_heights
    from fruitcli.tables import read_taxels
    from fruitcli.workflow.online_model import online_solver, reduced_source

    skin_table = scene.skin
    if o.skin_toml is not None:
        from fruitcli.sensing.detection.settings import check_skin_file
        from fruitcli.sensing.skin.heights import skin_with_gap_law

        skin_table = skin_with_gap_law(o.skin_toml)
        check_skin_file(o.skin_toml, settings.method)
    taxels_csv, states_npz, reduced, mesh_npz = _taxel_products(scene, scene_path, o, progress)
    taxels = read_taxels(taxels_csv, FrameError)
    states = load_states(states_npz, len(taxels)) if states_npz else None
    gain = detection_gain(gain_inputs(scene), taxels, o.gains_csv)
    heights = skin_heights(skin_table, taxels, settings, gain is not None)
    pressure = solver = None
    positions, state_kpa = taxels.xyz_mm, None
    if o.online:
        solver = (
            online_solver(scene, mesh_npz, taxels.xyz_mm, progress)
            if o.model_kind == "full"
            else reduced_source(reduced, taxels, taxels_csv)
        )
        positions = solver.taxels_mm
        pressure = PressureState(tuple(solver.model.chamber_names))
    elif states is not None and o.pressure_port:
        positions, state_kpa = states.taxels_mm, states.pressure_kpa
        pressure = PressureState(states.chamber_names)
    elif states is not None:
        positions = states.taxels_mm[0]
    loc = Locator(
        taxels,
        scene.board,
        positions,
        settings,
        state_kpa,
        where=str(taxels_csv),
        gain=gain,
        heights=heights,
    )
    return loc, pressure, solver


def outputs(
    live_loc: LiveLocator,
    taxels: Taxels,
    o: LiveOptions,
    osc_address: tuple | None,
    progress: Progress,
    pressure: PressureState | None,
) -> Outputs:
    """The live outputs (`fruitcli.sensing.live.outputs.Outputs`) of `taxels`: JSON
    lines, and TUIO, the log and the view when asked."""
    from fruitcli.sensing.live.outputs import Outputs

    out = Outputs(live_loc, taxels, progress, o.time_scale, pressure)
    if osc_address is not None:
        from fruitcli.sensing.outputs.tuio import Normalizer, TuioSender

        out.tuio = TuioSender(
            osc_address, Normalizer.from_taxels(taxels.i, taxels.j, taxels.xyz_mm), o.tuio_3d
        )
        progress(f"TUIO/OSC to {o.osc_target} ({osc_address[0]})")
    if o.log_path is not None:
        from fruitcli.sensing.live.run_log import RunLog

        out.log = RunLog(o.log_path, o.log_max_kb * 1024, o.log_backups)
    if o.view_target is not None:
        out.start_view(o.view_target)
    return out


def open_board(o: LiveOptions, progress: Progress) -> SerialBase:
    """The board's serial port; with --reconnect, waited for until it appears."""
    from fruitcli.sensing.live.serial_ports import open_port

    if not o.reconnect:
        return open_port(o.port, o.baud)
    from fruitcli.sensing.live.reconnect import wait_for_port

    try:
        return wait_for_port(
            o.port, o.baud, on_wait=lambda why: progress(f"{why}; waiting for it (--reconnect)")
        )
    except KeyboardInterrupt:
        click.echo("Interrupted.", err=True)
        raise SystemExit(130) from None


@dataclass
class Run:
    """The open board (its port and frame reader, replaced on a reconnect) and the frames
    seen so far."""

    ser: SerialBase
    reader: FrameReader
    seen: int = 0


def run_frames(
    run: Run,
    out: Outputs,
    o: LiveOptions,
    board: BoardSection,
    frame_format: str,
    progress: Progress,
) -> None:
    """Feed the board's frames to the outputs until --frames are seen (or forever);
    with --reconnect, a vanished port is waited for and reopened."""
    from fruitcli.sensing.live.idle_gc import FrameGC
    from fruitcli.sensing.live.serial_ports import PortClosed

    warned = False
    frame_gc = FrameGC().__enter__()  # garbage collection between frames, not in one
    try:
        while o.n_frames is None or run.seen < o.n_frames:
            try:
                got = run.reader.poll()
            except PortClosed:
                if not o.reconnect:
                    raise
                from fruitcli.sensing.live.reconnect import wait_for_port

                out.skipped += run.reader.skipped
                run.ser.close()
                run.ser, run.reader = out.reconnect(
                    o.port, o.baud, board, frame_format, wait_for_port
                )
                continue
            reader = run.reader
            if not run.seen and not warned and sum(reader.wrong_size.values()) >= 10:
                warned = True  # the board's frames do not fit [board]: say it once
                progress(
                    f"no frame yet, {reader.skipped} lines skipped: "
                    f"{reader.skip_reasons()} ([board] rows x cols)"
                )
            for counts, t_s, _ in got:
                out.frame(counts, reader.t0 + t_s)
                run.seen += 1
                if o.n_frames is not None and run.seen >= o.n_frames:
                    break
            frame_gc.after_frame()
    finally:
        frame_gc.__exit__()


def shut_down(
    run: Run,
    out: Outputs,
    threads: tuple,
    pser: SerialBase | None,
    pressure: PressureState | None,
    solver: OnlineSolver | ReducedOnline | None,
    progress: Progress,
) -> None:
    """Close the port and the outputs, let the online FEM finish its state (at most
    FEM_JOIN_S) and the pressure thread end (`threads`: (FEM, pressure), each None when
    not running), and say the summary."""
    fem_thread, p_thread = threads
    run.ser.close()
    out.close()
    if fem_thread is not None:
        fem_thread.join(0.5)  # an idle thread ends at once
    if fem_thread is not None and fem_thread.is_alive():
        progress("waiting for the online FEM to finish its state")
        fem_thread.join(FEM_JOIN_S)
        if fem_thread.is_alive():
            progress(f"the online FEM is still solving after {FEM_JOIN_S:g} s; leaving it")
    if p_thread is not None:
        p_thread.join(1.0)
    if pser is not None:
        pser.close()
    for line in summary(run.seen, run.reader, pressure, solver) + out.summary():
        progress(line)


def summary(
    seen: int,
    reader: FrameReader,
    pressure: PressureState | None,
    solver: OnlineSolver | ReducedOnline | None,
) -> list[str]:
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
