"""`fruit emulate-board`: a MuCa board on a pseudo-terminal, for use without hardware."""

from __future__ import annotations

import sys

import click

from fruitcli.cli.options import FiniteFloat, baud_option, format_option, fruit_errors


@click.command("emulate-board")
@click.option(
    "--from",
    "from_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Recording to play (.npz or MuCa ASCII log).",
)
@click.option(
    "--bench",
    "bench_dir",
    type=click.Path(),
    default=None,
    help="A scene (.toml: its bench runs first, into out/<scene name>) or the output "
    "folder of `fruit bench`: plays <indenter>/frames.npz (the first).",
)
@format_option(default="ascii", auto=False)
@baud_option(pace=True)
@click.option(
    "--fps",
    type=FiniteFloat(min=0),
    default=0.0,
    show_default=True,
    help="Cap on frames per second (0: no cap, the baud limits).",
)
@click.option(
    "--frames",
    "n_frames",
    type=click.IntRange(min=1),
    default=None,
    help="Play this many frames (default: the whole recording; 600 synthetic).",
)
@click.option(
    "--log-every",
    type=click.IntRange(min=0),
    default=0,
    help="Mix a board log line in after every N frames (0: never).",
)
@click.option(
    "--wait/--no-wait",
    default=True,
    show_default=True,
    help="Hold the stream until a reader opens the port.",
)
def emulate_board(from_path, bench_dir, fmt, baud, fps, n_frames, log_every, wait) -> None:
    """Open a pseudo-terminal, print its path, and play frames on it like a MuCa board
    running the stock firmware.

    ASCII: one line of rows x cols comma-separated counts per frame, \\r\\n; binary: one
    2 + rows x cols byte packet per frame; both after the '[Muca] ...' start-up lines.
    Without --from or --bench, plays a synthetic touch sweeping over an idle board.
    """
    from pathlib import Path

    from fruitcli.errors import FrameError
    from fruitcli.sensing.frames.board import BOARD_COLS, BOARD_ROWS
    from fruitcli.sensing.frames.recording import read_recording
    from fruitcli.sensing.live.board_emulator import (
        NO_READER_S,
        BoardEmulator,
        pacing_line,
        synthetic_frames,
    )

    with fruit_errors():
        if from_path and bench_dir:
            raise click.UsageError("give --from or --bench, not both")
        if bench_dir and str(bench_dir).endswith(".toml"):
            from fruitcli.scene import load_scene
            from fruitcli.workflow import planner

            scene = load_scene(bench_dir)
            if not scene.has("bench"):
                raise FrameError(f"{bench_dir}: the scene has no [bench] section")
            out = Path("out") / scene.name
            planner.run(scene, out, until="bench")
            bench_dir = out / "bench"
        if bench_dir:
            found = sorted(Path(bench_dir).glob("*/frames.npz")) or sorted(
                Path(bench_dir).glob("frames.npz")
            )
            if not found:
                raise FrameError(f"{bench_dir}: no <indenter>/frames.npz (run `fruit bench`)")
            from_path = found[0]
        if from_path:
            frames = read_recording(from_path).frames
            if frames.shape[1] > BOARD_ROWS or frames.shape[2] > BOARD_COLS:
                raise FrameError(
                    f"{from_path}: frames of {frames.shape[1]} x "
                    f"{frames.shape[2]}, expected at most {BOARD_ROWS} x "
                    f"{BOARD_COLS} (the MuCa board's Tx x Rx; skipLine gives "
                    "fewer)"
                )
            frames = frames[:n_frames] if n_frames else frames
        else:
            frames = synthetic_frames(n_frames or 600)
        if fmt == "binary" and log_every:
            raise click.UsageError(
                "--log-every: the binary firmware prints no lines between packets"
            )
        em = BoardEmulator(
            frames, fps, log_every=log_every, wait_for_reader=wait, fmt=fmt, baud=baud
        )
        click.echo(em.path)
        sys.stdout.flush()
        click.echo(
            f"{len(frames)} {frames.shape[1]} x {frames.shape[2]} frames, {fmt}; "
            f"pacing: {pacing_line(fmt, baud, frames=frames)}"
            + (f", capped at {fps:g} frames/s" if fps else ""),
            err=True,
        )
        try:
            sent = em.play()
        except KeyboardInterrupt:
            em.close()
            raise SystemExit(130) from None
    ending = (
        f"; stopped: nothing was read from the port for {NO_READER_S:g} s" if em.reader_gone else ""
    )
    click.echo(f"{sent} frames played{ending}", err=True)
