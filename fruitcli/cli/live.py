"""`fruit live`: localize touches live from a MuCa board; JSON lines on stdout (mm)."""

from __future__ import annotations

import sys

import click

from fruitcli.cli.options import Progress, fruit_errors, scene_products, shared_outputs


@click.command()
@click.argument("scene_path", metavar="SCENE", type=click.Path(dir_okay=False))
@click.option("--port", required=True, help="Serial port of the board.")
@click.option("--taxels", "taxels_csv", type=click.Path(dir_okay=False), default=None,
              help="Taxel CSV (id,i,j,x_mm,y_mm,z_mm); default: the scene's own (its stages "
                   "run into out/<scene name> when needed).")
@click.option("--states", "states_npz", type=click.Path(dir_okay=False), default=None,
              help="states.npz: taxels follow the FEM states (state 0 without pressures).")
@click.option("--pressure-port", default=None,
              help="Serial source of chamber pressures: lines 'P c1=2.5 c2=0.0' in kPa.")
@click.option("--online", is_flag=True,
              help="Solve the FEM at every new measured pressure (in a background thread; "
                   "needs --pressure-port and the scene's mesh) instead of interpolating "
                   "the precomputed states.")
@click.option("--frames", "n_frames", type=click.IntRange(min=1), default=None,
              help="Stop after this many frames (baseline frames included).")
@click.option("--baud", type=click.IntRange(min=1), default=115200, show_default=True)
@click.option("--format", "fmt", type=click.Choice(["auto", "ascii", "binary"]), default=None,
              help="The board's frame format (stock Muca_Raw ASCII or SendRawByte binary); "
                   "default: the scene's [board].format (auto-detected).")
@click.option("--baseline-frames", type=click.IntRange(min=1), default=None,
              help="Frames averaged into the baseline C0 (default: the scene's).")
@click.option("--threshold", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Touch threshold, counts (default: the scene's).")
def live(scene_path, port, taxels_csv, states_npz, pressure_port, online, n_frames, baud,
         fmt, baseline_frames, threshold):
    """Stream touches of every frame from PORT as JSON lines on stdout.

    One line per frame with touches, and one with "touches": [] when they end:
    {"frame", "t_s", "touches": [{"touch", "i", "j", "x_mm", "y_mm", "z_mm", "peak"}]}.
    """
    import threading

    from fruitcli.errors import FrameError
    from fruitcli.scene import load_scene
    from fruitcli.sensing.board import load_taxels
    from fruitcli.sensing.live import LiveLocator, pressure_thread
    from fruitcli.sensing.locate import load_states
    from fruitcli.sensing.pipeline import Locator, Settings
    from fruitcli.sensing.serial_io import FrameReader, PortClosed, PressureState, open_port

    progress = Progress("[live] ")
    stop = threading.Event()
    with fruit_errors():
        scene = load_scene(scene_path)
        settings = Settings.from_scene(scene["detection"], baseline_frames=baseline_frames,
                                       threshold_counts=threshold)
        if n_frames is not None and n_frames <= settings.baseline_frames:
            raise FrameError(f"--frames {n_frames}: expected more than the "
                             f"{settings.baseline_frames} baseline frames (--baseline-frames "
                             "or the scene's [detection]); nothing could be located")
        taxels_csv = taxels_csv or scene["grid"]["taxels"]
        if online:  # the scene's mesh (tetra), not its states
            taxels_csv, mesh_npz = online_products(scene, scene_path, taxels_csv,
                                                   pressure_port, progress)
        elif taxels_csv is None:
            taxels_csv, found_states = scene_products(scene)
            states_npz = states_npz or found_states
        if taxels_csv is None:
            raise FrameError(f"{scene_path}: no taxels: give --taxels or [grid].taxels")
        if pressure_port and not online and not states_npz:
            raise FrameError(f"--pressure-port {pressure_port}: nothing uses the pressures; "
                             "it needs --states or --online, or the scene's states")
        taxels = load_taxels(taxels_csv)
        board = scene["board"]
        states = load_states(states_npz, len(taxels)) if states_npz else None
        pressure = solver = None
        if online:
            solver = online_solver(scene, mesh_npz, taxels.xyz_mm, progress)
            loc = Locator(taxels, board, solver.taxels_mm, settings, where=str(taxels_csv))
            pressure = PressureState(tuple(solver.model.chamber_names))
        elif states is None:
            loc = Locator(taxels, board, taxels.xyz_mm, settings, where=str(taxels_csv))
        elif pressure_port:
            loc = Locator(taxels, board, states.taxels_mm, settings, states.pressure_kpa,
                          where=str(taxels_csv))
            pressure = PressureState(states.chamber_names)
        else:
            loc = Locator(taxels, board, states.taxels_mm[0], settings, where=str(taxels_csv))
        ser = open_port(port, baud)
        pser = p_thread = fem_thread = None
        if pressure is not None:
            pser = open_port(pressure_port, baud)
            p_thread = pressure_thread(pser, pressure, stop, pressure_port)
        if solver is not None:  # nothing to solve until a pressure line arrived
            fem_thread = solver.run(lambda: pressure.kpa if pressure.received else None, stop)
        reader = FrameReader(ser, board["rows"], board["cols"], name=port,
                             fmt=fmt or board["format"])
        live_loc = LiveLocator(loc, pressure, solver)
        progress(f"collecting {settings.baseline_frames} baseline frames from {port}")
        seen = 0
        warned = False
        try:
            while n_frames is None or seen < n_frames:
                got = reader.poll()
                if not seen and not warned and sum(reader.wrong_size.values()) >= 10:
                    warned = True  # the board's frames do not fit [board]: say it once
                    progress(f"no frame yet, {reader.skipped} lines skipped: "
                             f"{reader.skip_reasons()} ([board] rows x cols)")
                for counts, t_s, _ in got:
                    line = live_loc.push(counts, t_s)
                    seen += 1
                    if line is not None:
                        sys.stdout.write(line + "\n")
                        sys.stdout.flush()
                    if n_frames is not None and seen >= n_frames:
                        break
        except PortClosed:
            why = reader.skip_reasons()
            raise FrameError(f"{port}: port closed after {seen} frames "
                             f"({reader.skipped} lines skipped{': ' + why if why else ''})"
                             ) from None
        except KeyboardInterrupt:
            click.echo("Interrupted.", err=True)
            raise SystemExit(130) from None
        finally:
            stop.set()
            ser.close()
            if fem_thread is not None:
                fem_thread.join(0.5)  # an idle thread ends at once
            if fem_thread is not None and fem_thread.is_alive():
                progress("waiting for the online FEM to finish its state")
                fem_thread.join(FEM_JOIN_S)
                if fem_thread.is_alive():
                    progress(f"the online FEM is still solving after {FEM_JOIN_S:g} s; "
                             "leaving it")
            if p_thread is not None:
                p_thread.join(1.0)
                pser.close()
            for line in _summary(seen, reader, pressure, solver):
                progress(line)


FEM_JOIN_S = 30.0
"""How long `fruit live` waits at exit for the online FEM's current state (a state takes
tens of ms; a hard one with load subdivisions a few seconds)."""


def _summary(seen, reader, pressure, solver) -> list[str]:
    """The closing lines of `fruit live`: frames, skipped lines, online FEM."""
    why = reader.skip_reasons()
    lines = [f"{seen} frames, {reader.skipped} lines skipped" + (f": {why}" if why else "")]
    if pressure is not None:
        lines.append(f"pressure lines: {pressure.received} taken, {pressure.skipped} skipped "
                     f"(not 'P name=kPa ...' with known chambers {', '.join(pressure.chambers)} "
                     "and finite values)")
        if pressure.closed:
            lines.append("the pressure port closed during the run: the taxels kept the last "
                         "pressures received")
    if solver is not None:
        lines.append(solver.summary())
    return lines


def online_products(scene, scene_path, taxels_csv, pressure_port, progress):
    """(taxels CSV, mesh.npz) for `fruit live --online`: the scene's stages up to tetra,
    run into out/<scene name> when needed (one planner run); given taxels are kept."""
    from pathlib import Path

    from fruitcli import planner
    from fruitcli.errors import FrameError
    from fruitcli.stages import taxels_path

    if not pressure_port:
        raise FrameError("--online: needs --pressure-port, the source of the pressures")
    if not scene.chambers:
        raise FrameError(f"{scene_path}: --online: the scene has no [[geometry.chamber]]")
    out = Path("out") / scene.name
    steps = planner.run(scene, out, until="tetra", progress=progress, shared=shared_outputs(out))
    skipped = [st for st in steps if st.stage == "tetra" and st.action == "not needed"]
    if skipped:
        raise FrameError(f"{scene_path}: --online: the scene is not meshed ({skipped[0].reason}); "
                         "give [actuation] pressures for its chambers")
    ctx = planner.Context(out)
    return taxels_csv or taxels_path(scene, ctx), ctx.dir("tetra") / "mesh.npz"


def online_solver(scene, mesh_npz, taxels_xyz, progress):
    """The OnlineSolver of `fruit live --online` on the scene's mesh, with the taxels
    mapped into it."""
    from fruitcli.fem import barycentric, io
    from fruitcli.fem.online import OnlineSolver
    from fruitcli.fem.stage import build_model, solver_options

    model = build_model(scene, io.load_mesh(mesh_npz))
    tet, w, _ = barycentric.locate(model.rest, model.tets, taxels_xyz)
    progress(f"online FEM: {len(model.tets)} tets, chambers {', '.join(model.chamber_names)}")
    return OnlineSolver(model, tet, w, solver_options(scene),
                        solver_options(scene, first_state=bool(model.jigs)))
